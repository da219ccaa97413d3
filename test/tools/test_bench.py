"""`rearrangement-bench physics`: the throughput record is complete and measured in contact."""

import json

import pytest

from rearrangement_planner.tools.bench.command import main


def test_physics_benchmark_writes_a_complete_record(tmp_path, capsys):
    out = tmp_path / "physics.json"
    assert main(["physics", "--seconds", "0.3", "--json", str(out)]) == 0
    record = json.loads(out.read_text())
    assert json.loads(capsys.readouterr().out) == record
    one, seven = record["results"]
    assert (one["objects"], seven["objects"]) == (1, 7)
    assert record["warm_up_s"] >= 0.0      # compiled before the clock, reported apart
    for result in (one, seven):
        assert result["steps"] > 0 and result["steps_per_second"] > 0
        assert result["compiled_steps_per_second"] > 0
        # the sweep really pushes, and not with the hand alone
        assert result["steps_pushing_share"] > 0.5
        assert "panda_link5" in result["pushing_links"]


def test_bench_without_a_command_runs_the_benchmark(capsys):
    """No command (or options only) means `run`; its options are checked before anything runs."""
    assert main(["--time-limit", "0"]) == 2
    assert capsys.readouterr().err == ("rearrangement-bench: --time-limit: must be a positive "
                                       "number of seconds, got 0.0\n")
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    assert all(command in out for command in ("run", "generate", "physics", "scenes"))


def test_physics_and_scenes_reject_non_positive_times(capsys):
    assert main(["physics", "--seconds", "0"]) == 2
    assert "--seconds" in capsys.readouterr().err
    assert main(["scenes", "--time-limit", "-1"]) == 2
    assert "--time-limit" in capsys.readouterr().err
    assert main(["scenes", "--set", "trees=0"]) == 2
    assert "--set: trees=0: trees must be in [1, 64], got 0" in capsys.readouterr().err


def test_scenes_benchmark_reports_one_line_per_run(tmp_path, capsys):
    from rearrangement_planner.tools.bench.command import main

    out = tmp_path / "runs.jsonl"
    assert main(["scenes", "--scenes", "easy_push", "--planners", "darrt", "static-rrt",
                 "--seeds", "1", "--time-limit", "30", "--jsonl", str(out)]) == 0
    rows = [json.loads(line) for line in out.read_text().splitlines()]
    assert [(r["planner"], r["seed"], r["trees"]) for r in rows] == [("darrt", 1, 2),
                                                                     ("static-rrt", 1, 2)]
    assert all(r["outcome"] == "SUCCEEDED" and r["moved"] == ["target"] for r in rows)
    assert capsys.readouterr().out.count("\n") == 2
