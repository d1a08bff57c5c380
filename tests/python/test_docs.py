"""The documentation holds together: the generated variables page is current,
every relative link resolves, every page says its kind, the README stays a
short entry point, and no user-facing page names an issue number.

Needs no built FMU: it reads the committed files only.
"""

from __future__ import annotations

import importlib.util
import re
import unicodedata
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
README = REPO / "README.md"
PAGES = sorted((REPO / "docs").rglob("*.md"))
"""Every page under docs/ (docs/ARCHITECTURE.md included once it exists)."""
KIND = re.compile(r"^\*(Guide|Reference|Design|Results|Index)\b")
LINK = re.compile(r"(?<!!)\[[^\]]*\]\(([^)\s]+)\)|!\[[^\]]*\]\(([^)\s]+)\)")
ISSUE = re.compile(r"\bissues?\s*#?\d+", re.IGNORECASE)


def _generator():
    spec = importlib.util.spec_from_file_location("variables_reference", REPO / "scripts" / "variables_reference.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _slug(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"[`*_]", "", heading.strip().lower())
    kept = "".join(c for c in text if c in " -" or unicodedata.category(c)[0] in "LN")
    return kept.replace(" ", "-")


def _anchors(page: Path) -> set[str]:
    text = re.sub(r"```.*?```", "", page.read_text(), flags=re.DOTALL)
    return {_slug(m.group(1)) for m in re.finditer(r"^#+\s+(.*)$", text, flags=re.MULTILINE)}


def _links(page: Path):
    text = re.sub(r"```.*?```", "", page.read_text(), flags=re.DOTALL)
    text = re.sub(r"`[^`\n]*`", "", text)
    for m in LINK.finditer(text):
        target = m.group(1) or m.group(2)
        if not re.match(r"^[a-z]+:", target):
            yield target


def test_variables_page_is_generated_from_the_model_descriptions():
    gen = _generator()
    page = REPO / "docs" / "reference" / "variables.md"
    assert page.read_text() == gen.render(gen.models()), (
        "docs/reference/variables.md is stale: run python3 scripts/variables_reference.py")


def test_variables_page_lists_every_variable_of_every_fmu():
    gen = _generator()
    text = (REPO / "docs" / "reference" / "variables.md").read_text()
    for model in gen.models():
        assert f"## {model['name']}" in text
        for v in model["variables"]:
            assert f"| `{v['name']}` |" in text, (model["name"], v["name"])


@pytest.mark.parametrize("page", [README, REPO / "BENCHMARKS.md"] + PAGES, ids=lambda p: str(p.relative_to(REPO)))
def test_relative_links_resolve(page):
    broken = []
    for target in _links(page):
        path, _, anchor = target.partition("#")
        dest = (page.parent / path).resolve() if path else page
        if not dest.exists():
            broken.append(target)
        elif anchor and dest.suffix == ".md" and anchor not in _anchors(dest):
            broken.append(target)
    assert not broken, f"{page.relative_to(REPO)}: broken links {broken}"


@pytest.mark.parametrize("page", PAGES + [REPO / "BENCHMARKS.md"], ids=lambda p: str(p.relative_to(REPO)))
def test_every_page_says_its_kind(page):
    head = page.read_text().splitlines()[:6]
    assert any(KIND.match(line) for line in head), (
        f"{page.relative_to(REPO)}: no '*Guide*', '*Reference*', '*Design*', '*Results*' or '*Index*' line at the top")


def test_every_docs_page_is_in_the_index():
    index = (REPO / "docs" / "README.md").read_text()
    for page in PAGES:
        rel = page.relative_to(REPO / "docs").as_posix()
        if rel not in ("README.md", "ARCHITECTURE.md"):
            assert f"]({rel})" in index, rel


def test_readme_is_a_short_entry_point():
    lines = README.read_text().splitlines()
    assert len(lines) <= 150, len(lines)
    head = "\n".join(lines[:8])
    assert "scripts/demo.sh" in head and "scripts/test.sh" in head


@pytest.mark.parametrize("page", [README] + PAGES, ids=lambda p: str(p.relative_to(REPO)))
def test_no_issue_numbers_in_user_facing_pages(page):
    hits = [m.group(0) for m in ISSUE.finditer(page.read_text())]
    assert not hits, f"{page.relative_to(REPO)}: {hits}"


GENERATORS = ["examples/stability.rs", "examples/work_precision.py", "examples/paper_figures.py",
              "examples/sweep_dask.py", "scripts/memory_check.py",
              "examples/musculotendon_stiffness.py"]
"""The scripts that write a results page under docs/."""


@pytest.mark.parametrize("generator", GENERATORS)
def test_every_generator_writes_the_results_header(generator):
    text = (REPO / generator).read_text()
    assert "provenance.header()" in text or "provenance::header()" in text, (
        f"{generator} must open its page with the provenance header")
    assert not ISSUE.search(text), f"{generator} names an issue number"


def test_the_provenance_header_is_a_results_kind_line():
    spec = importlib.util.spec_from_file_location("provenance", REPO / "scripts" / "provenance.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    header = module.header()
    assert KIND.match(header) and "machine: " in header and "commit " in header, header
