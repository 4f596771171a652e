"""The documentation resolves what the code cites, and the gallery holds every example.

Code comments and docstrings cite pages of the documentation by their path in the repository:
"docs/theory.md Eq. N", "docs/theory.md section N" (or "docs/theory.md N", "N.M"), and
"docs/diagnosis_method.md 2.6 rule N" / "2.3 step N" / "3.2".  These tests read the source tree
(no Sphinx needed), so a citation the page lacks, or one of a document outside the repository,
fails the test suite, not only the documentation build.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
THEORY = ROOT / "docs" / "theory.md"
METHOD = ROOT / "docs" / "diagnosis_method.md"
#: the code, and the aircraft presets whose notes cite the theory page
SOURCES = sorted([*(ROOT / "src" / "fdml").rglob("*.py"), *(ROOT / "src" / "fdml").rglob("*.json")])

#: "docs/theory.md Eq. 5", "Eqs. 13-17", "Eqs. 2 and 10", "Eq. BS-12"
_EQ = re.compile(r"docs/theory\.md\s+Eqs?\.\s*((?:BS-)?\d+(?:\s*(?:-|–|,|and)\s*(?:BS-)?\d+)*)")
#: "docs/theory.md section 7", "docs/theory.md section 4 finite-state form, section 8 gust"
_SECTION = re.compile(r"docs/theory\.md\s+(?:section|§)\s*(\d+)(?:[^\n]{0,40}?,\s*section\s*(\d+))?")
#: bare numbers: "docs/theory.md 7", "docs/theory.md 11.2", "docs/theory.md 10, 11.5"
_BARE = re.compile(r"docs/theory\.md\s+(\d+(?:\.\d+)?(?:,\s*\d+(?:\.\d+)?)*)")
#: "docs/diagnosis_method.md 2.6 rule 5", "2.3 step 7", "3.2", "2.1 and 2.6 rule 1"
_METHOD = re.compile(
    r"docs/diagnosis_method\.md\s+(\d\.\d(?:\s+(?:rule|step)\s+\d+)?(?:\s+and\s+\d\.\d(?:\s+(?:rule|step)\s+\d+)?)*)"
)
#: documents outside the repository, which a clone cannot resolve
_OUTSIDE = re.compile(r"THEORY\.md|DIAGNOSIS\.md|STYLE\.md|shared/docs")


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


def _cited_bare_sections() -> set[str]:
    cited: set[str] = set()
    for path in SOURCES:
        for group in _BARE.findall(path.read_text(encoding="utf-8")):
            cited |= set(re.split(r",\s*", group))
    return cited


def _cited_method_places() -> set[tuple[str, str, str]]:
    """(section, "rule"/"step"/"", number) for every diagnosis-method citation."""
    cited: set[tuple[str, str, str]] = set()
    for path in SOURCES:
        for group in _METHOD.findall(path.read_text(encoding="utf-8")):
            for part in re.split(r"\s+and\s+", group):
                m = re.fullmatch(r"(\d\.\d)(?:\s+(rule|step)\s+(\d+))?", part.strip())
                assert m, part
                cited.add((m[1], m[2] or "", m[3] or ""))
    return cited


def test_the_scan_finds_the_citations():
    # the regular expressions must see what the code cites, or the tests below prove nothing
    eqs, sections = _cited_equations(), _cited_sections()
    assert {"5", "11", "13", "17", "24"} <= eqs
    assert {"4", "6", "7", "8"} <= sections
    assert {"7", "11.2"} <= _cited_bare_sections()
    assert {("2.6", "rule", "5"), ("2.3", "step", "7"), ("3.2", "", "")} <= _cited_method_places()


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: str(p.relative_to(ROOT / "src")))
def test_no_citation_of_a_document_outside_the_repository(path):
    lines = path.read_text(encoding="utf-8").splitlines()
    outside = [f"{n}: {line.strip()}" for n, line in enumerate(lines, 1) if _OUTSIDE.search(line)]
    assert not outside, f"{path.name} cites documents a clone does not have:\n" + "\n".join(outside)


@pytest.mark.parametrize("number", sorted(_cited_equations()))
def test_every_cited_equation_is_on_the_theory_page(number):
    assert f"\\tag{{{number}}}" in THEORY.read_text(encoding="utf-8"), (
        f"the code cites docs/theory.md Eq. {number}; the page has no \\tag{{{number}}}"
    )


@pytest.mark.parametrize("number", sorted(_cited_sections(), key=int))
def test_every_cited_section_is_on_the_theory_page(number):
    text = THEORY.read_text(encoding="utf-8")
    assert re.search(rf"^\(theory-{number}\)=\n## {number}\. ", text, re.M), (
        f"the code cites docs/theory.md section {number}; the page has no section {number}"
    )


@pytest.mark.parametrize("number", sorted(_cited_bare_sections()))
def test_every_cited_bare_section_is_on_the_theory_page(number):
    # "docs/theory.md 7" is section 7 (a "## 7." heading), "docs/theory.md 11.2" subsection 11.2
    level = "###" if "." in number else "##"
    pattern = rf"^{level} {re.escape(number)}[. ]"
    assert re.search(pattern, THEORY.read_text(encoding="utf-8"), re.M), (
        f"the code cites docs/theory.md {number}; the page has no heading {number}"
    )


def _method_section(text: str, section: str) -> str:
    """The body of section ``section`` ("2.6") of the diagnosis-method page, up to the next heading."""
    m = re.search(
        rf"^\(diagnosis-{section.replace('.', '-')}\)=\n### {re.escape(section)} [^\n]*\n(.*?)(?=^#)", text, re.M | re.S
    )
    return m[1] if m else ""


@pytest.mark.parametrize("place", sorted(_cited_method_places()), ids=lambda place: " ".join(x for x in place if x))
def test_every_cited_diagnosis_rule_is_on_the_method_page(place):
    section, kind, number = place
    body = _method_section(METHOD.read_text(encoding="utf-8"), section)
    assert body, f"the code cites docs/diagnosis_method.md {section}; the page has no section {section}"
    if kind:
        assert f"**{kind.capitalize()} {number}.**" in body, (
            f"the code cites docs/diagnosis_method.md {section} {kind} {number}; section {section} has none"
        )


@pytest.mark.parametrize("path", sorted((ROOT / "examples").glob("plot_*.py")), ids=lambda p: p.name)
def test_every_example_has_a_gallery_title(path):
    # sphinx-gallery executes every examples/plot_*.py (docs/conf.py) and titles it by the
    # first line of its docstring, underlined
    doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8")))
    assert doc, f"{path.name} has no docstring"
    title, underline = doc.splitlines()[:2]
    assert title.strip() and set(underline.strip()) == {"="} and len(underline.strip()) >= len(title.strip())
