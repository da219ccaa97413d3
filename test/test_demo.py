"""The interim demo: a straight push of the default scene's goal object, simulated."""

from rearrangement_planner.demo import main, straight_push
from rearrangement_planner.resources import scenes_dir


def test_default_scene_straight_push_reaches_the_goal():
    report = straight_push(str(scenes_dir() / "default.yaml"))
    assert report["goal_reached"], report
    assert report["goal_distance_after_m"] < report["goal_distance_before_m"]
    assert "target" in report["moved_objects"] and report["pushing_links"]


def test_seven_objects_block_the_straight_push():
    report = straight_push(str(scenes_dir() / "seven_objects.yaml"))
    assert not report["goal_reached"]
    assert report["stopped_because"].startswith("invalid step")


def test_bad_scene_exits_2_with_the_field(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text("robot: panda\ntable: {center: [0.5, 0.0], size: [0.8, -1.0], height: 0}\n"
                   "objects: []\ngoal: {object: x, position: [0.5, 0]}\n")
    assert main([str(bad)]) == 2
    assert "table.size" in capsys.readouterr().err
