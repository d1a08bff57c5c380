#!/usr/bin/env python3
"""Write docs/reference/variables.md: every variable of every shipped FMU.

The tables are read from the committed ``modelDescription/*.xml`` (the
generator's output, checked by ``tests/model_description.rs``), so the page
cannot disagree with the FMUs. ``tests/python/test_docs.py`` fails when the
committed page differs from what this script writes::

    python3 scripts/variables_reference.py            # rewrite the page
    python3 scripts/variables_reference.py --check    # exit 1 if it is stale

Standard library only.
"""

from __future__ import annotations

import argparse
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
XML_DIR = REPO / "modelDescription"
PAGE = REPO / "docs" / "reference" / "variables.md"
FIRST = ("HillMuscle1D", "HillMuscleFE")
"""The two full FMUs lead; the scenes follow in name order."""
CAUSALITY_ORDER = {"input": 0, "output": 1, "parameter": 2}


def _cell(text) -> str:
    return "" if text is None else str(text).replace("|", "\\|").replace("\n", " ")


def read(path: Path) -> dict:
    """The facts of one modelDescription the page shows."""
    root = ET.parse(path).getroot()
    variables = []
    for sv in root.find("ModelVariables"):
        typed = next(iter(sv))
        variables.append({
            "name": sv.get("name"), "vr": sv.get("valueReference"), "causality": sv.get("causality"),
            "variability": sv.get("variability"), "type": typed.tag, "unit": typed.get("unit", ""),
            "start": typed.get("start", ""), "min": typed.get("min", ""), "max": typed.get("max", ""),
            "description": sv.get("description", ""),
        })
    cs = root.find("CoSimulation")
    experiment = root.find("DefaultExperiment")
    return {"name": root.get("modelName"), "identifier": cs.get("modelIdentifier"), "guid": root.get("guid"),
            "description": root.get("description"), "variables": variables,
            "experiment": dict(experiment.attrib) if experiment is not None else {}}


def models() -> list[dict]:
    found = {p.stem: read(p) for p in sorted(XML_DIR.glob("*.xml"))}
    order = [n for n in FIRST if n in found] + sorted(n for n in found if n not in FIRST)
    return [found[n] for n in order]


def _names(model, causality):
    return ", ".join(f"`{v['name']}`" for v in model["variables"] if v["causality"] == causality) or "—"


def render(all_models: list[dict]) -> str:
    lines = [
        "# Variables of the shipped FMUs",
        "",
        "*Reference, generated* by `python3 scripts/variables_reference.py` from `modelDescription/*.xml`; do not",
        "edit by hand (`tests/python/test_docs.py` fails when this page is stale). What the inputs and outputs mean",
        "over a step: [conventions.md](conventions.md); what happens outside the ranges: [bad-input.md](bad-input.md).",
        "",
        "Parameters are `fixed` (set before `fmi2ExitInitializationMode`) but `threads` of the FE models, which is "
        "`tunable` (also set between steps; it changes no result); min and max are enforced when set.",
        "Until the `length` input is set it equals `L0` (its XML start is the default `L0`).",
        "",
        "## At a glance",
        "",
        "| FMU | what | inputs | outputs | variables |",
        "|---|---|---|---|---|",
    ]
    for m in all_models:
        lines.append(f"| [`{m['name']}`](#{m['name'].lower()}) | {_cell(m['description'])} | {_names(m, 'input')} | "
                     f"{_names(m, 'output')} | {len(m['variables'])} |")
    for m in all_models:
        e = m["experiment"]
        lines += [
            "",
            f"## {m['name']}",
            "",
            f"{_cell(m['description'])}. Model identifier `{m['identifier']}`, GUID `{m['guid']}`; default "
            f"experiment {e.get('startTime', '?')} to {e.get('stopTime', '?')} s, step {e.get('stepSize', '?')} s.",
            "",
            "| name | causality | type | unit | start | min | max | description |",
            "|---|---|---|---|---|---|---|---|",
        ]
        ordered = sorted(m["variables"], key=lambda v: (CAUSALITY_ORDER.get(v["causality"], 9), int(v["vr"])))
        for v in ordered:
            lines.append(f"| `{v['name']}` | {v['causality']} | {v['type']} | {_cell(v['unit'])} | "
                         f"{_cell(v['start'])} | {_cell(v['min'])} | {_cell(v['max'])} | {_cell(v['description'])} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true", help="exit 1 if the committed page is stale")
    parser.add_argument("--out", type=Path, default=PAGE)
    args = parser.parse_args(argv)
    text = render(models())
    if args.check:
        if not args.out.exists() or args.out.read_text() != text:
            print(f"{args.out} is stale: run python3 scripts/variables_reference.py", file=sys.stderr)
            return 1
        return 0
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
