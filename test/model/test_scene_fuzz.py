"""Property test: the shipped scenes, mutated the way a hostile or careless user
would (wrong types, NaN and inf, huge integers, deep nesting, aliases, raw bytes), either load
as a valid scene or are refused with one `RearrangementError` line of bounded length; never
another exception, never more than a couple of seconds. Derandomized: the same examples on
every run."""

from __future__ import annotations

import copy
import math
import time
from pathlib import Path
from typing import Any

import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rearrangement_planner.model.errors import RearrangementError
from rearrangement_planner.model.resources import scenes_dir
from rearrangement_planner.model.scene import Scene
from rearrangement_planner.physics.validation import load_scene

DEEP: list = ["deep"]
for _ in range(40):
    DEEP = [DEEP]
"""Nested 41 deep: past the loader's nesting limit."""

SCENES = {p.stem: yaml.safe_load(p.read_text()) for p in sorted(scenes_dir().glob("*.yaml"))}

VALUES = st.one_of(
    st.none(), st.booleans(), st.text(max_size=20), st.integers(),
    st.just(10**400), st.just(-(10**400)),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([1e308, -1e308, 1e-300, 0.0, -1.0, 1e6]),
    st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=4),
    st.dictionaries(st.text(max_size=5), st.integers(), max_size=3),
    st.just(DEEP),
)


def _paths(data: Any, prefix: tuple = ()) -> list[tuple]:
    """Every key/index path into a scene's data, at most 5 deep."""
    found = [prefix] if prefix else []
    if len(prefix) >= 5:
        return found
    if isinstance(data, dict):
        for key, value in data.items():
            found += _paths(value, prefix + (key,))
    elif isinstance(data, list):
        for i, value in enumerate(data):
            found += _paths(value, prefix + (i,))
    return found


def _set(data: Any, path: tuple, value: Any) -> None:
    for key in path[:-1]:
        data = data[key]
    data[path[-1]] = value


@st.composite
def mutated_scene_text(draw) -> str:
    name = draw(st.sampled_from(sorted(SCENES)))
    data = yaml.safe_load(yaml.safe_dump(SCENES[name]))
    for _ in range(draw(st.integers(1, 3))):
        _set(data, draw(st.sampled_from(_paths(data))), copy.deepcopy(draw(VALUES)))
    try:
        text = yaml.safe_dump(data, allow_unicode=True)
    except (yaml.YAMLError, OverflowError, ValueError):
        text = repr(data)                       # not YAML at all: must still be refused
    trick = draw(st.sampled_from(["", "alias", "bytes", "truncate", "tab"]))
    if trick == "alias":
        text = "x: &x [1, 2]\n" + text.replace("radius:", "radius: *x\nignored:", 1)
    elif trick == "truncate":
        text = text[: draw(st.integers(0, len(text)))]
    elif trick == "tab":
        text = text.replace("  ", "\t", 1)
    elif trick == "bytes":
        text = text + "\udcff"                  # written below as a lone surrogate byte
    return text


@settings(max_examples=120, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(text=mutated_scene_text())
def test_a_mutated_scene_loads_or_is_refused_in_one_line(text, tmp_path_factory, panda):
    path: Path = tmp_path_factory.mktemp("fuzz") / "scene.yaml"
    path.write_bytes(text.encode("utf-8", errors="surrogateescape"))
    started = time.monotonic()
    try:
        scene = load_scene(path, robot=panda if "robot: panda" in text else None)
    except RearrangementError as exc:
        message = str(exc)
        assert "\n" not in message and 0 < len(message) < 600, message
    else:
        assert isinstance(scene, Scene)
        assert all(math.isfinite(o.mass) for o in scene.objects)
    assert time.monotonic() - started < 3.0
