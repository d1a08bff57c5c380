"""The musculotendon stiffness study (examples/musculotendon_stiffness.py) on a tiny grid.

- The page's tables: a row per tendon, a column pair (error, cost) per step,
  every cell a finite number; the page opens with the provenance header and
  states the result at h = 1 ms.
- With ``adaptive_substeps`` off (one backward-Euler step per communication
  step) the force error against the h/100 run falls with h, for a compliant
  and a rigid tendon.
"""

from __future__ import annotations

import math
import re

import pytest

import musculotendon_stiffness as ms

GRID = dict(programs=ms.PROGRAMS[:1] + ms.PROGRAMS[3:], eps0s=(0.04, None), steps=(1e-3, 1e-2), t_end=0.5)


@pytest.fixture(scope="module")
def cells():
    if not ms.FMU.is_file():
        pytest.fail(f"{ms.FMU} not found: build the FMUs first with `scripts/build_fmus.sh`", pytrace=False)
    return ms.study(**GRID)


def test_the_tables_have_a_row_per_tendon_and_a_finite_cell_per_step(cells):
    assert len(cells) == 2 * 2 * 2
    assert all(not c.failure and math.isfinite(c.error) and c.wall_per_s > 0 for c in cells)
    for program in GRID["programs"]:
        lines = ms.table(cells, program.key, ms.DEFAULT_TOLERANCE).splitlines()
        assert lines[0] == ("| tendon | h = 0.001 s: error / F0 | ms per s | h = 0.01 s: error / F0 | ms per s |")
        assert [line.split("|")[1].strip() for line in lines[2:]] == ["eps0 = 0.04", "rigid"]
        for line in lines[2:]:
            values = [v.strip() for v in line.strip("|").split("|")[1:]]
            assert len(values) == 4 and all(math.isfinite(float(v)) for v in values), line


def test_the_page_opens_with_the_header_and_states_the_result(cells):
    text = ms.page(cells, [ms.DEFAULT_TOLERANCE], "examples/musculotendon_stiffness.py --quick")
    assert text.startswith("*Results, generated.*")
    assert re.search(r"largest error at h = 1 ms over the programs is \*\*[0-9.e+-]+ F0\*\*", text)
    assert text.count("| tendon |") == len(GRID["programs"])


def test_without_substeps_the_error_falls_with_h():
    cells = ms.study(**GRID, extra={"adaptive_substeps": False})
    for program in GRID["programs"]:
        for tendon in ("eps0 = 0.04", "rigid"):
            e = {c.h: c.error for c in cells if c.program == program.key and c.tendon == tendon}
            assert e[1e-3] < 0.5 * e[1e-2], (program.key, tendon, e)
