"""Where a generated results page came from: the kind line every generator
writes first (docs/README.md: a results page names its command, machine and
commit). ``testkit::provenance`` writes the same line for the Rust ones."""

from __future__ import annotations

import datetime
import os
import platform
import subprocess
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def machine() -> str:
    """CPU model, logical cores and operating system."""
    cpu = platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    system = platform.system()
    try:
        for line in Path("/etc/os-release").read_text().splitlines():
            if line.startswith("PRETTY_NAME="):
                system = line.split("=", 1)[1].strip('"')
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} cores, {system}"


def commit() -> str:
    """Short hash of HEAD (``+changes`` when tracked files differ) and today's date."""
    def git(*args: str) -> str | None:
        try:
            out = subprocess.run(["git", *args], cwd=REPO, capture_output=True, text=True, check=True)
        except (OSError, subprocess.CalledProcessError):
            return None
        return out.stdout.strip()

    sha = git("rev-parse", "--short", "HEAD") or "unknown"
    dirty = bool(git("status", "--porcelain", "--untracked-files=no"))
    return f"{sha}{'+changes' if dirty else ''} ({datetime.date.today().isoformat()})"


def header() -> str:
    """The page's kind line: ``*Results, generated.* Command below; machine: …; commit ….``"""
    return f"*Results, generated.* Command below; machine: {machine()}; commit {commit()}."
