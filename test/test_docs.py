"""The reference docs stay true to the code: every setting they name exists, and the README's
layout map lists every module of the package.

docs/experiments.md and CHANGELOG.md are logs: they name settings that were removed (with the
commit to revive them from), so they are not checked here."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from rearrangement_planner.planning.requests.request import request_settings
from rearrangement_planner.ros.parameters import PARAMETERS

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
