"""The documentation resolves what the code cites, and the gallery holds every example.

Code comments and docstrings cite "THEORY.md Eq. N" and "THEORY.md section N"; docs/theory.md
restates the theory with the same numbers.  These tests read the source tree (no Sphinx needed),
so a citation of an equation or section the page lacks fails the test suite, not only the
documentation build.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
THEORY = ROOT / "docs" / "theory.md"
SOURCES = sorted((ROOT / "src" / "fdml").rglob("*.py"))

#: "THEORY.md Eq. 5", "THEORY.md Eqs. 13-17", "THEORY.md Eqs. 2 and 10", "THEORY.md Eq. BS-12"
_EQ = re.compile(r"THEORY(?:\.md)?\s+Eqs?\.\s*((?:BS-)?\d+(?:\s*(?:-|–|,|and)\s*(?:BS-)?\d+)*)")
#: "THEORY.md section 7", "THEORY.md section 4 finite-state form, section 8 gust"
_SECTION = re.compile(r"THEORY(?:\.md)?\s+(?:section|§)\s*(\d+)(?:[^\n]{0,40}?,\s*section\s*(\d+))?")


def _cited_equations() -> set[str]:
    cited: set[str] = set()
    for path in SOURCES:
        for group in _EQ.findall(path.read_text(encoding="utf-8")):
            bs = group.strip().startswith("BS-")
            parts = re.split(r"\s*(?:,|and)\s*", group)
            for part in parts:
                nums = [int(n) for n in re.findall(r"\d+", part)]
                if re.search(r"\d\s*[-–]\s*(?:BS-)?\d", part) and len(nums) == 2:
                    nums = list(range(nums[0], nums[1] + 1))  # "13-17" is a range
                cited |= {f"BS-{n}" if bs else str(n) for n in nums}
    return cited


def _cited_sections() -> set[str]:
    cited: set[str] = set()
    for path in SOURCES:
        for first, second in _SECTION.findall(path.read_text(encoding="utf-8")):
            cited |= {s for s in (first, second) if s}
    return cited


def test_the_scan_finds_the_citations():
    # the regular expressions must see what the code cites, or the tests below prove nothing
    eqs, sections = _cited_equations(), _cited_sections()
    assert {"5", "11", "13", "17", "24"} <= eqs
    assert {"4", "6", "7", "8"} <= sections


@pytest.mark.parametrize("number", sorted(_cited_equations()))
def test_every_cited_equation_is_on_the_theory_page(number):
    assert f"\\tag{{{number}}}" in THEORY.read_text(encoding="utf-8"), (
        f"the code cites THEORY.md Eq. {number}; docs/theory.md has no \\tag{{{number}}}"
    )


@pytest.mark.parametrize("number", sorted(_cited_sections(), key=int))
def test_every_cited_section_is_on_the_theory_page(number):
    text = THEORY.read_text(encoding="utf-8")
    assert re.search(rf"^\(theory-{number}\)=\n## {number}\. ", text, re.M), (
        f"the code cites THEORY.md section {number}; docs/theory.md has no section {number}"
    )


@pytest.mark.parametrize("path", sorted((ROOT / "examples").glob("plot_*.py")), ids=lambda p: p.name)
def test_every_example_has_a_gallery_title(path):
    # sphinx-gallery executes every examples/plot_*.py (docs/conf.py) and titles it by the
    # first line of its docstring, underlined
    doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8")))
    assert doc, f"{path.name} has no docstring"
    title, underline = doc.splitlines()[:2]
    assert title.strip() and set(underline.strip()) == {"="} and len(underline.strip()) >= len(title.strip())
