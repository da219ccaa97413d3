"""The reference docs stay true to the code: every setting they name exists, the README's
layout map lists every module of the package, the results tables are what
`rearrangement-bench report` prints from the committed summaries, and every link to a section
lands on a heading.

docs/experiments.md and CHANGELOG.md are logs: they name settings that were removed (with the
commit to revive them from), so they are not checked here."""

from __future__ import annotations

import functools
import re
import unicodedata
from pathlib import Path

import pytest

from rearrangement_planner.planning.requests.request import request_settings
from rearrangement_planner.ros.parameters import PARAMETERS
from rearrangement_planner.tools.bench.report import report

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ["README.md", "docs/design.md", "docs/benchmark.md"]
SOURCES = sorted((ROOT / "rearrangement_planner").rglob("*.py")) \
    + sorted((ROOT / "msg_adapters").rglob("*.py"))
NAME = re.compile(r"`([a-z][a-z0-9]*(?:_[a-z0-9]+)+)(?:=[^`]*)?`")
"""A backticked snake_case name (with at least one underscore), optionally `name=value`."""
SET = re.compile(r"--set[ =]([a-z][a-z0-9_]*)=")


def _identifiers() -> set[str]:
    words: set[str] = set()
    for path in SOURCES:
        words |= set(re.findall(r"[A-Za-z_][A-Za-z0-9_]*", path.read_text()))
    return words


@pytest.mark.parametrize("doc", REFERENCE)
def test_every_setting_a_reference_doc_names_exists(doc):
    """A backticked snake_case name is a setting, a node parameter or a name in the code; a
    `--set NAME=` names a setting of the plan request."""
    text = (ROOT / doc).read_text()
    settings = {s.name for s in request_settings()} | {p.name for p in PARAMETERS}
    known = settings | _identifiers()
    unknown = sorted({name for name in NAME.findall(text) if name not in known})
    assert not unknown, f"{doc} names what the code does not have: {unknown}"
    unset = sorted({name for name in SET.findall(text) if name not in settings})
    assert not unset, f"{doc} sets what is no setting: {unset}"


def test_the_checks_see_a_removed_setting():
    """The pattern finds names as the docs write them (so the test above can fail)."""
    assert NAME.findall("`edge_margin` and `max_turn=5` but not `Physics` or `a.py`") == \
        ["edge_margin", "max_turn"]
    assert "edge_margin" not in _identifiers()
    assert SET.findall("rearrangement-plan x --set push_bias=0 --set=k_actions=2") == \
        ["push_bias", "k_actions"]


def test_the_readme_layout_map_lists_every_module():
    text = (ROOT / "README.md").read_text()
    start = text.index("## Layout")
    end = text.find("\n## ", start + 1)
    layout = text[start:end if end > 0 else None]
    missing = [str(path.relative_to(ROOT)) for path in SOURCES
               if path.name != "__init__.py" and path.name not in layout]
    assert not missing, f"modules missing from the README's layout map: {missing}"


LOST_CITATIONS = re.compile(r"DESIGN §|STYLE \d|[Ii]ssue #?\d|[Ss]ession \d|§[IVX]+\S* of 00[02]"
                            r"|\b00[02]_[0-9a-f]{6}")
"""Citations a reader of the repository cannot follow: the design file that lived outside it,
the style guide, the tracker's issue numbers, the lab notebook's sessions, papers by file id."""


def test_the_code_cites_what_a_reader_can_follow():
    """Papers by author, year and section; the design as docs/design.md."""
    config = sorted((ROOT / "config").rglob("*.yaml"))
    tests = [p for p in sorted((ROOT / "test").rglob("*.py")) if p.name != "test_docs.py"]
    found = [f"{path.relative_to(ROOT)}:{n}: {line.strip()}"
             for path in SOURCES + config + tests
             for n, line in enumerate(path.read_text().splitlines(), 1)
             if LOST_CITATIONS.search(line)]
    assert not found, "\n".join(found)
    assert LOST_CITATIONS.search("(DESIGN §5, issue 18)") and LOST_CITATIONS.search("§V of 000")


RESULTS = re.compile(r"<!-- results: rearrangement-bench report (?P<files>[^>]*?) -->\n"
                     r"(?P<table>.*?)<!-- /results -->", re.S)
"""A generated results table: the command that prints it in the opening comment, the files
it reads named there and nowhere else."""


@pytest.mark.parametrize("doc", ["README.md", "docs/benchmark.md"])
def test_the_results_tables_are_what_the_report_prints(doc):
    """Each marked block equals `rearrangement-bench report` run on the summaries its marker
    names (paths from the repository's root), so no figure of it is retyped or drifts."""
    text = (ROOT / doc).read_text()
    blocks = RESULTS.findall(text)
    assert blocks, f"{doc} has no results table (<!-- results: rearrangement-bench report ... -->)"
    assert len(blocks) == text.count("<!-- results:") == text.count("<!-- /results -->"), \
        f"{doc}: a results marker without its pair"
    for files, table in blocks:
        printed = report([ROOT / name for name in files.split()])
        assert table.strip() == printed, (
            f"{doc}: the table differs from what `rearrangement-bench report {files}` prints; "
            f"paste its output between the markers")


LINK = re.compile(r"\[[^\]]*\]\((?!https?:)([^)#\s]*)#([^)\s]+)\)")
"""A Markdown link to a section: [text](path#anchor) or [text](#anchor)."""


def _outside_code(text: str) -> list[str]:
    """The lines of a Markdown text outside fenced code blocks."""
    lines, fenced = [], False
    for line in text.splitlines():
        if line.startswith("```"):
            fenced = not fenced
        elif not fenced:
            lines.append(line)
    return lines


def anchor(heading: str) -> str:
    """GitHub's anchor of a heading: its text (link targets dropped) in lower case, every
    character but letters, digits, '-', '_' and spaces removed, spaces made '-'."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", heading).strip().lower()
    kept = "".join(c for c in text if c in " -_" or unicodedata.category(c)[0] in "LNM")
    return kept.replace(" ", "-")


@functools.lru_cache
def _anchors(path: Path) -> frozenset[str]:
    """The anchors of a Markdown file's headings (a repeated one gets -1, -2, ...)."""
    anchors, counts = set(), {}
    for line in _outside_code(path.read_text()):
        match = re.match(r"#{1,6} (.*)", line)
        if match:
            slug = anchor(match.group(1))
            n = counts.get(slug, 0)
            counts[slug] = n + 1
            anchors.add(slug if n == 0 else f"{slug}-{n}")
    return frozenset(anchors)


def test_every_link_to_a_section_lands_on_a_heading():
    """README.md and docs/*.md: a relative link with a #anchor names a heading of its file (a
    section that moved, as the benchmark's dated ones to docs/experiments.md, breaks it)."""
    broken = []
    for doc in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        for line in _outside_code(doc.read_text()):
            for target, slug in LINK.findall(line):
                path = (doc.parent / target).resolve() if target else doc
                if not path.is_file() or slug not in _anchors(path):
                    broken.append(f"{doc.relative_to(ROOT)}: {target}#{slug}")
    assert not broken, "links to no heading:\n" + "\n".join(broken)


def test_the_anchor_rule_is_githubs():
    assert anchor("Plans that survive the world: the one protocol at the close (2026-11-30)") == \
        "plans-that-survive-the-world-the-one-protocol-at-the-close-2026-11-30"
    assert anchor("End to end: the shipped default against first plans (seeds 0–2)") == \
        "end-to-end-the-shipped-default-against-first-plans-seeds-02"
    assert anchor("A fragile best's extra candidates within 10,000 iterations each") == \
        "a-fragile-bests-extra-candidates-within-10000-iterations-each"
    assert anchor("2026-12-06 — The 3D judge's timestep: 2 ms (adopted)") == \
        "2026-12-06--the-3d-judges-timestep-2-ms-adopted"
    assert anchor("`graze_penalty` in [docs](x.md)") == "graze_penalty-in-docs"
