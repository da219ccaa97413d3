"""`rearrangement-bench report`: the results table from summary.json files, today's and older
ones, the same text for the same files. (That README.md and docs/benchmark.md carry it
verbatim: test/test_docs.py.)"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from rearrangement_planner.tools.bench import trials as benchmark
from rearrangement_planner.tools.bench.command import main
from rearrangement_planner.tools.bench.report import HEAD, protocol_cell, report

ROOT = Path(__file__).resolve().parents[2]
ONE_PROTOCOL = ROOT / "docs/benchmark/one_protocol"


def _row(solved: bool, **columns: str) -> dict:
    row = dict.fromkeys(benchmark.CSV_COLUMNS, "")
    row.update(scene="v1_s0", objects="1", planner="pc-rrt", seed="0", time_limit="60.0",
               solved=str(int(solved)), plan_time_s="2.0" if solved else "60.0",
               iterations="10", outcome="SUCCEEDED" if solved else "TIMEOUT")
    if solved:
        row.update(path_length_rad_before="10", path_length_rad_after="8",
                   ee_path_length_m_before="2.0", ee_path_length_m_after="1.5",
                   object_displacement_m_before="0.4", object_displacement_m_after="0.4",
                   shortcut_time_s="1.0", pushing_links="panda_hand", non_goal_objects_moved="0",
                   executed_ideal="1", executed_object_contacts="0", trajectory_s="8.0",
                   goal_push_path_m="0.3", goal_start_distance_m="0.3", goal_turn_rad="0.1")
    row.update(columns)
    return row


def test_a_run_of_today_fills_every_column(tmp_path):
    """Both engines and the closed loop, through `benchmark.summarize` (so the report reads the
    keys a run writes today)."""
    rows = [_row(True, executed_servo="1", executed_pybullet="1", executed_both="1",
                 executed_toppled="0", executed_pybullet_toppled="0", robustness="0.9",
                 perturbed_trials="2", perturbed_reached="2", perturbed_reached_pybullet="1",
                 perturbed_reached_both="1", replan="1", replan_reached="1",
                 time_to_goal_s="10.0"),
            _row(True, executed_servo="1", executed_pybullet="0", executed_both="0",
                 executed_toppled="0", executed_pybullet_toppled="1", robustness="0.3",
                 perturbed_trials="2", perturbed_reached="1", perturbed_reached_pybullet="1",
                 perturbed_reached_both="0", replan="1", replan_reached="0",
                 time_to_goal_s="30.0"),
            _row(False, replan="1")]
    protocol = {"scenes": ["v1_s0", "v1_s1", "v1_s2"], "scene_sets": ["varied"],
                "planners": ["pc-rrt"], "seeds": [0, 1, 2], "time_limit": 60.0,
                "request_settings": {"trees": 1}, "quick": False, "robot": "panda"}
    path = tmp_path / "summary.json"
    path.write_text(json.dumps(benchmark.summarize(rows, protocol)))
    head, rule, row = report([path]).split("\n")
    assert head == "| " + " | ".join(HEAD) + " |" and rule == "|" + "---|" * len(HEAD)
    assert row == ("| 3 varied scenes, seeds 0–2, 60 s, trees=1 | pc-rrt | 2 "
                   "| 1/3 (33 %), both engines | 2/3 (67 %) | 1/3 (33 %) "
                   "| 1/2 (50 %); MuJoCo 0, PyBullet 1 "
                   "| 1/4 (25 %); MuJoCo 3, PyBullet 2 "
                   "| 0.40 / 0.250 | 2.0 / 48.4 s "
                   "| 1/3 (33 %) within 1 re-plan / 20.0 s (open loop 10.0 s) |")


def test_a_summary_from_before_pybullet_says_mujoco_and_leaves_the_rest_out():
    """The committed one-protocol run of f9ba799: reached in MuJoCo alone, no closed loop."""
    lines = report([ONE_PROTOCOL / "varied_pc_rrt/summary.json"]).split("\n")
    assert lines[2] == ("| 35 varied scenes, seeds 0–2, 60 s | pc-rrt | 99 "
                        "| 52/105 (50 %), MuJoCo | – | – | 18/99 (18 %) | 256/495 (52 %) "
                        "| 0.19 / 0.205 | 0.8 / 11.3 s | – |")
    # older still: no perturbed executions, no calibration, no scene set
    older = report([ROOT / "docs/benchmark/default/summary.json"]).split("\n")
    assert older[2] == ("| 35 scenes, seeds 0–2, 60 s | pc-rrt | 93 | 60/105 (57 %), MuJoCo "
                        "| – | – | 10/93 (11 %) | – | – | 21.2 / 60.2 s | – |")
    assert len(older) == 2 + 5        # its five planners, in the summary's order
    assert [line.split(" | ")[1] for line in older[2:4]] == ["pc-rrt", "slice-rrt"]


def test_one_row_per_run_and_planner_in_the_order_given_the_same_every_time(capsys):
    paths = [str(ONE_PROTOCOL / name / "summary.json")
             for name in ("fixed_pc_rrt", "varied_slice_rrt", "varied_pc_rrt")]
    assert main(["report", *paths]) == 0
    first = capsys.readouterr().out
    assert main(["report", *paths]) == 0
    assert capsys.readouterr().out == first == report([Path(p) for p in paths]) + "\n"
    rows = first.splitlines()[2:]
    assert [(r.split(" | ")[0][2:], r.split(" | ")[1]) for r in rows] == [
        ("35 fixed scenes, seeds 0–2, 60 s", "pc-rrt"),
        ("35 varied scenes, seeds 0–2, 60 s", "slice-rrt"),
        ("35 varied scenes, seeds 0–2, 60 s", "pc-rrt")]


@pytest.mark.parametrize("content, problem", [
    (None, "No such file or directory"),
    ("not json", "not JSON"),
    ('{"trials": 3}', "not the summary.json of a `rearrangement-bench run`")])
def test_a_file_that_is_no_summary_is_one_line_and_exit_2(content, problem, tmp_path, capsys):
    path = tmp_path / "summary.json"
    if content is not None:
        path.write_text(content)
    assert main(["report", str(path)]) == 2
    out = capsys.readouterr()
    assert out.out == ""
    assert out.err.startswith(f"rearrangement-bench: SUMMARY.json: {path}: ")
    assert problem in out.err and out.err.count("\n") == 1
    with pytest.raises(SystemExit) as exc:       # at least one file
        main(["report"])
    assert exc.value.code == 2


def test_the_protocol_cell_names_scenes_seeds_and_budget():
    assert protocol_cell({"scenes": ["n1_s0"] * 14, "scene_sets": ["fixed"], "seeds": [0],
                          "time_limit": 20.0, "quick": True}) == \
        "14 fixed scenes (quick), seed 0, 20 s"
    assert protocol_cell({"scenes": ["a", "b"], "scene_sets": ["file", "varied"],
                          "seeds": [10, 9], "time_limit": 60.0}) == \
        "2 varied scenes, seeds 9, 10, 60 s"
    assert protocol_cell({"scenes": ["a"], "scene_set": "varied", "seeds": [3, 4, 5, 7]}) == \
        "1 varied scenes, seeds 3, 4, 5, 7"
