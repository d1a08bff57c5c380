#!/usr/bin/env bash
# Shared set-up for scripts/demo.sh and scripts/test.sh: a Python venv in .venv
# with the pinned requirements (reinstalled only when requirements.txt changes),
# and .venv/bin first on PATH. Source it from the repository root. It sets no
# shell options (the scripts that source it run under `set -euo pipefail`), so
# sourcing it in an interactive shell leaves that shell as it was; a failed
# step returns non-zero.
PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
  echo "== creating .venv"
  "$PY" -m venv .venv || return 1
fi
want=$(sha256sum requirements.txt | cut -d' ' -f1) || return 1
have=$(cat .venv/.requirements.sha256 2>/dev/null || true)
if [ "$want" != "$have" ]; then
  echo "== installing requirements.txt into .venv"
  .venv/bin/python -m pip install --quiet --disable-pip-version-check -r requirements.txt || return 1
  echo "$want" > .venv/.requirements.sha256
fi
export PATH="$PWD/.venv/bin:$PATH"
