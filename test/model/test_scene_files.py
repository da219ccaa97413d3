"""Hostile scene files and robot configs: each is refused with exit 2 and one line
naming the field or file and the problem; no traceback, no hang, no absurd world accepted, no
noise on the terminal. Driven through `rearrangement-plan` (in process, fd-level capture), the
way a user meets them."""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest
import yaml

from rearrangement_planner.model.files import MAX_FILE_BYTES
from rearrangement_planner.model.resources import robots_dir, scenes_dir
from rearrangement_planner.tools.cli import main

EASY = yaml.safe_load((scenes_dir() / "easy_push.yaml").read_text())


def run(capfd, *args: str) -> tuple[int, str]:
    """Exit code and everything written to stderr (fd 2: C libraries included)."""
    started = time.monotonic()
    code = main([*args, "--quiet", "--trees", "1"])
    assert time.monotonic() - started < 10.0, "took too long"
    return code, capfd.readouterr().err


def scene_file(tmp_path: Path, change=None, text: str | None = None, name="scene.yaml") -> str:
    data = yaml.safe_load(yaml.safe_dump(EASY))
    if change is not None:
        change(data)
    path = tmp_path / name
    path.write_text(text if text is not None else yaml.safe_dump(data))
    return str(path)


def refused(capfd, path: str) -> str:
    """The one stderr line of a refused scene (exit 2)."""
    code, err = run(capfd, path)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "Traceback" not in err, err
    assert len(lines[0]) < 400, lines[0]
    return lines[0]


# -- numbers ------------------------------------------------------------------------------------


def test_a_400_digit_integer_is_refused_without_echoing_it(tmp_path, capfd):
    def huge(d):
        d["objects"][0]["mass"] = 10**400
    assert "objects[0].mass: must be a finite number (kg), got an integer of 401 digits" \
        in refused(capfd, scene_file(tmp_path, huge))


def test_a_400_digit_integer_in_a_vector_is_refused(tmp_path, capfd):
    def huge(d):
        d["objects"][0]["pose"][0] = -(10**400)
    assert "objects[0].pose: entry 0 is not a finite number" in refused(
        capfd, scene_file(tmp_path, huge))


def test_a_huge_float_prints_no_numpy_warning(tmp_path, capfd):
    def huge(d):
        d["objects"][0]["size"] = [1e308, 1e308, 1e308]
    assert "objects[0].size: every entry must be between 0.005 and 1 m" in refused(
        capfd, scene_file(tmp_path, huge))


def test_a_1e300_value_is_not_printed_with_300_digits(tmp_path, capfd):
    def huge(d):
        d["goal"]["radius"] = 1e300
    assert refused(capfd, scene_file(tmp_path, huge)).endswith("got 1e+300")


# -- bytes and text -----------------------------------------------------------------------------


def test_non_utf8_scene_is_named(tmp_path, capfd):
    path = tmp_path / "latin1.yaml"
    path.write_bytes((scenes_dir() / "easy_push.yaml").read_bytes() + b"# caf\xe9\n")
    assert "is not UTF-8 text (byte 0xe9 on line" in refused(capfd, str(path))


def test_non_utf8_robot_config_is_named(tmp_path, capfd):
    config = tmp_path / "robot.yaml"
    config.write_bytes(b"name: \xff\xfe\n")
    assert "robot config" in refused(
        capfd, scene_file(tmp_path, lambda d: d.update(robot=str(config))))


def test_a_binary_urdf_is_named(tmp_path, capfd):
    config = yaml.safe_load((robots_dir() / "panda.yaml").read_text())
    (tmp_path / "robot.urdf").write_bytes(bytes(range(256)) * 4)
    config["urdf"] = str(tmp_path / "robot.urdf")
    (tmp_path / "robot.yaml").write_text(yaml.safe_dump(config))
    line = refused(capfd, scene_file(tmp_path, lambda d: d.update(
        robot=str(tmp_path / "robot.yaml"))))
    assert "URDF" in line and "is not UTF-8 text" in line


def test_a_urdf_that_is_not_xml_prints_no_parser_noise(tmp_path, capfd):
    config = yaml.safe_load((robots_dir() / "panda.yaml").read_text())
    (tmp_path / "robot.urdf").write_text("this is not xml {")
    config["urdf"] = str(tmp_path / "robot.urdf")
    (tmp_path / "robot.yaml").write_text(yaml.safe_dump(config))
    assert "the URDF is not XML" in refused(capfd, scene_file(tmp_path, lambda d: d.update(
        robot=str(tmp_path / "robot.yaml"))))


def test_a_system_file_is_refused_without_echoing_it(capfd):
    line = refused(capfd, "/etc/passwd")
    assert "a scene must be a mapping" in line or "not valid YAML" in line


# -- structure ----------------------------------------------------------------------------------


@pytest.mark.parametrize("key", ["robot", "table"])
def test_deep_nesting_is_refused(tmp_path, capfd, key):
    text = yaml.safe_dump(EASY).replace(f"{key}:", f"{key}: " + "[" * 1000 + "]" * 1000
                                        + f"\nunused_{key}:", 1)
    assert "nests collections more than 20 deep" in refused(
        capfd, scene_file(tmp_path, text=text))


def test_a_yaml_alias_bomb_is_refused_at_once(tmp_path, capfd):
    levels = ['a0: &a0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    for i in range(1, 10):
        levels.append(f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 9) + "]")
    text = "\n".join(levels) + "\n" + yaml.safe_dump(EASY).replace(
        "shape: box", "shape: *a9", 1)
    assert "uses a YAML alias" in refused(capfd, scene_file(tmp_path, text=text))


def test_a_huge_scene_is_refused_before_parsing(tmp_path, capfd):
    text = yaml.safe_dump(EASY) + "#" * (MAX_FILE_BYTES + 10)
    assert f"at most {MAX_FILE_BYTES:,} are read" in refused(
        capfd, scene_file(tmp_path, text=text))


def test_a_fifo_does_not_hang(tmp_path, capfd):
    fifo = tmp_path / "x.yaml"
    os.mkfifo(fifo)
    assert "is not a regular file" in refused(capfd, str(fifo))


def test_a_300_character_robot_name_is_refused(tmp_path, capfd):
    line = refused(capfd, scene_file(tmp_path, lambda d: d.update(robot="r" * 300)))
    assert line.startswith("rearrangement-plan: robot:") and "r" * 100 not in line


# -- absurd worlds ------------------------------------------------------------------------------


def test_an_obstacle_off_the_table_is_refused(tmp_path, capfd):
    def far(d):
        d["obstacles"] = [{"name": "post", "shape": "box", "size": [0.05, 0.05, 0.3],
                           "pose": [0.6, 1e308, 0.0]}]
    assert "obstacles[0].pose: obstacle 'post' at (0.6, 1e+308) is off the table" in refused(
        capfd, scene_file(tmp_path, far))


def test_a_goal_region_larger_than_the_table_is_refused(tmp_path, capfd):
    assert "goal.radius: 3 m is larger than the table" in refused(
        capfd, scene_file(tmp_path, lambda d: d["goal"].update(radius=3.0)))


@pytest.mark.parametrize(("field", "value", "expected"), [
    ("size", [1e6, 1e6], "table.size: every entry must be between 0.1 and 5 m"),
    ("height", 1e6, "table.height: must be between -2 and 2 m"),
])
def test_an_absurd_table_is_refused(tmp_path, capfd, field, value, expected):
    assert expected in refused(capfd, scene_file(tmp_path, lambda d: d["table"].update(
        {field: value})))


@pytest.mark.parametrize(("field", "value", "expected"), [
    ("mass", 1e300, "objects[0].mass: must be between 0.001 and 100 kg"),
    ("mass", 1e-300, "objects[0].mass: must be between 0.001 and 100 kg"),
    ("support_friction", 1e300, "objects[0].support_friction: must be between 0.01 and 2"),
    ("pusher_friction", -0.1, "objects[0].pusher_friction: must be between 0 and 2"),
    ("size", [1e-9, 0.05, 0.1], "objects[0].size: every entry must be between 0.005 and 1 m"),
])
def test_absurd_objects_are_refused(tmp_path, capfd, field, value, expected):
    assert expected in refused(capfd, scene_file(tmp_path, lambda d: d["objects"][0].update(
        {field: value})))


# -- output paths -------------------------------------------------------------------------------


@pytest.mark.parametrize(("option", "target", "expected"), [
    ("--json", "/tmp", "--json '/tmp' is a folder"),
    ("--json", "/nonexistent/x.json", "--json '/nonexistent/x.json': the folder"),
    ("--plot", "/tmp", "--plot '/tmp' is a folder"),
    ("--record", "/tmp", "--record '/tmp' is a folder"),
])
def test_bad_output_paths_are_refused_before_planning(capfd, option, target, expected):
    started = time.monotonic()
    code, err = run(capfd, "easy_push", option, target)
    assert code == 2 and expected in err and time.monotonic() - started < 2.0, err


def test_the_design_bounds_table_is_the_code():
    """docs/design.md's scene-file table states BOUNDS as they are."""
    from rearrangement_planner.model.scene import BOUNDS

    readme = (Path(__file__).resolve().parents[2] / "docs" / "design.md").read_text()
    rows = {
        "table.center": "| `table.center` (each) | {} to {} m from the robot base |",
        "table.size": "| `table.size` (each) | {} to {} m |",
        "table.height": "| `table.height` | {} to {} m |",
        "obstacle extent": "| obstacle `size` (each) | {} to {} m |",
        "object extent": "| object `size` (each), `height` | {} to {} m |",
        "object radius": "| object `radius` | {} to {} m |",
        "mass": "| `mass` | {} to {} kg |",
        "support_friction": "| `support_friction` | {} to {} |",
        "pusher_friction": "| `pusher_friction` | {} to {} |",
        "goal.radius": "| `goal.radius` | {} to {} m, and at most the table's larger side |",
    }
    assert set(rows) == set(BOUNDS)
    for name, row in rows.items():
        low, high, _ = BOUNDS[name]
        assert row.format(f"{low:g}", f"{high:g}") in readme, name
