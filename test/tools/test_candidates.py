"""`rearrangement-bench candidates` (tools/bench/candidates.py): candidate plans recorded and
executed in MuJoCo, selection rules replayed over them as `pipeline._robust_search` chooses."""

import json

import pytest

from rearrangement_planner.model.resources import scenes_dir
from rearrangement_planner.tools.bench.candidates import Rule, choose, replay_table, rules
from rearrangement_planner.tools.bench.command import main


def _candidate(k, search, robustness=0.0, travel=0.3, reached=False, toppled=0, solved=True):
    record = {"scene": "s", "seed": 0, "k": k, "solved": solved, "search_s": search}
    if solved:
        record.update(shortcut_s=0.5, rollouts_s=0.5, robustness=robustness,
                      goal_travel_m=travel, goal_turn_rad=1.0, reached=reached,
                      goal_distance_m=0.05 if reached else 0.2, toppled=toppled)
    return record


def test_choose_ranks_within_the_budget_as_the_robust_search_does():
    records = [_candidate(0, 10.0, robustness=0.4, travel=0.2),
               _candidate(1, 10.0, robustness=0.1, travel=0.4, reached=True),
               _candidate(2, 10.0, robustness=0.8, travel=0.9, toppled=1),
               _candidate(3, 30.0, robustness=0.9, travel=0.1, reached=True)]
    assert choose(records, Rule("first", 1, None), 60.0)["k"] == 0
    assert choose(records, Rule("robust", 3, 0.0), 60.0)["k"] == 2
    # Ranks with 0.5 per metre: 0.3, -0.1, 0.35 (the third); with 1: 0.2, -0.3, -0.1 (the first).
    assert choose(records, Rule("p0.5", 3, 0.5), 60.0)["k"] == 2
    assert choose(records, Rule("p1", 3, 1.0), 60.0)["k"] == 0
    assert choose(records, Rule("oracle", 3, oracle=True), 60.0)["k"] == 1
    # The fourth search (30 s) starts with 60 - 33 = 27 s left: it would not have finished.
    assert choose(records, Rule("robust", 4, 0.0), 60.0)["k"] == 2
    assert choose(records, Rule("robust", 4, 0.0), 70.0)["k"] == 3
    # A candidate robust in every rollout ends the search: later ones are never planned.
    records[0]["robustness"] = 1.0
    assert choose(records, Rule("robust", 4, 0.0), 70.0)["k"] == 0
    unsolved = [_candidate(0, 60.2, solved=False)]
    assert choose(unsolved, Rule("first", 1, None), 60.0) is None


def test_choose_bounds_the_later_searches_by_the_first_plans_iterations():
    """With effort 1 a later search that needs more iterations than the first plan took
    (at least 100) ends at that bound without a plan, after the share of its time."""
    records = [_candidate(0, 2.0, robustness=0.4) | {"iterations": 300},
               _candidate(1, 10.0, robustness=0.9) | {"iterations": 1500},
               _candidate(2, 1.0, robustness=0.6) | {"iterations": 150}]
    assert choose(records, Rule("all", 3, 0.0), 60.0)["k"] == 1
    assert choose(records, Rule("bounded", 3, 0.0, effort=1.0), 60.0)["k"] == 2
    assert choose(records, Rule("bounded", 3, 0.0, effort=5.0), 60.0)["k"] == 1
    # 2 s + 0.5 + 0.5, then 10 s x 300 / 1500: the second search is cut after 2 s.
    assert choose(records, Rule("bounded", 3, 0.0, effort=1.0), 5.1)["k"] == 0
    assert choose(records, Rule("bounded", 3, 0.0, effort=1.0), 6.1)["k"] == 2


def test_replay_table_counts_the_chosen_plans():
    records = [_candidate(0, 5.0, robustness=0.2, reached=False, toppled=1),
               _candidate(1, 5.0, robustness=0.6, reached=True)]
    table = replay_table(records, rules(2, 0.5), 60.0)
    assert "| first plan | 1/1 | 0/1 (0 %) | 1 |" in table
    assert "| most robust of 2 | 1/1 | 1/1 (100 %) | 0 |" in table
    assert "| best of 2 by MuJoCo (oracle) | 1/1 | 1/1 (100 %) | 0 |" in table


def test_candidates_command_records_executes_and_replays(tmp_path, capsys):
    scene = str(scenes_dir() / "easy_push.yaml")
    # Seed 5: both candidates plan easy_push in well under the budget (20 and 670
    # iterations), so that a loaded machine does not time the second one out.
    args = ["candidates", "--scenes", scene, "--seeds", "5", "--candidates", "2",
            "--time-limit", "20", "--set", "rollouts=5", "--workers", "1", "--out",
            str(tmp_path)]
    assert main(args) == 0
    lines = (tmp_path / "candidates.jsonl").read_text().splitlines()
    records = [json.loads(line) for line in lines]
    assert [(r["scene"], r["seed"], r["k"]) for r in records] == [("easy_push", 5, 0),
                                                                  ("easy_push", 5, 1)]
    for record in records:
        assert record["solved"] and 0.0 <= record["robustness"] <= 1.0
        assert record["goal_travel_m"] > 0.05 and isinstance(record["reached"], bool)
        assert record["goal_distance_m"] >= 0.0 and record["search_s"] > 0.0
        assert record["iterations"] > 0
    out = capsys.readouterr().out
    assert "| first plan | 1/1 |" in out and "most robust of 2" in out
    assert "of 2, later searches <= 1 x the first's iterations |" in out
    # Resumable: a second run records nothing new.
    assert main(args) == 0
    assert (tmp_path / "candidates.jsonl").read_text().splitlines() == lines


@pytest.mark.parametrize("option, value", [("--candidates", "0"), ("--set", "rollouts=0"),
                                           ("--set", "travel_penalty=-1"),
                                           ("--time-limit", "0"), ("--workers", "99"),
                                           ("--set", "nope=1"), ("--set", "max_turn=-1"),
                                           ("--set", "transit_time_limit=3")])
def test_candidates_command_names_a_bad_option(option, value, capsys, tmp_path):
    assert main(["candidates", option, value, "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert option in err and value in err
    assert not (tmp_path / "candidates.jsonl").exists()


def test_record_request_plans_with_the_given_settings():
    """`--set` reaches every candidate search: one iteration cannot solve easy_push."""
    from rearrangement_planner.tools.bench.candidates import record_request

    scene = scenes_dir() / "easy_push.yaml"
    records = record_request(scene, 1, 1, 20.0, {"max_iterations": 1, "rollouts": 1})
    assert [(r["k"], r["solved"]) for r in records] == [(0, False)]
