"""The benchmarks' execution engine (`tools.bench.engine`): Ray tasks streamed as they finish, the
progress bar, and a real two-node Ray cluster on this machine (`ray start --head` and
`ray start --address` as separate process groups) that a benchmark run spreads its trials over."""

from __future__ import annotations

import csv
import io
import operator
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from rearrangement_planner.tools.bench import command as bench
from rearrangement_planner.tools.bench.engine import Engine, EngineError, Job, Progress


class _Tty(io.StringIO):
    def isatty(self):
        return True


def test_progress_counts_done_failed_and_left_with_the_time_left():
    stream = io.StringIO()                                   # not a terminal: lines only
    progress = Progress(4, stream)
    progress.advance(True, "n1_s0 pc-rrt seed 0: SUCCEEDED")
    progress.advance(False, "n1_s1 pc-rrt seed 0: ERROR", failed=True)
    progress.close()
    lines = stream.getvalue().splitlines()
    assert len(lines) == 2 and "\r" not in stream.getvalue()
    assert lines[0].startswith("1/4 trials, 1 solved, 0 failed, 3 left, ")
    assert lines[1].startswith("2/4 trials, 1 solved, 1 failed, 2 left, ")
    assert "left  n1_s1 pc-rrt seed 0: ERROR" in lines[1]


def test_progress_draws_a_bar_in_place_on_a_terminal():
    stream = _Tty()
    progress = Progress(4, stream)
    progress.advance(True, "a")
    progress.advance(False, "b")
    progress.close()
    text = stream.getvalue()
    assert "\r" in text and "2/4" in text and "50%" in text
    assert "1 solved, 0 failed, 2 left" in text and "#####" in text


def test_tasks_stream_their_results_and_a_failure_is_a_traceback():
    engine = Engine()                                        # the embedded Ray
    jobs = [Job("half", (1, 2)), Job("zero", (1, 0), label="1/0"),
            Job("big", (9, 3), cpus=64)]                     # more CPUs than a node has
    done = {d.job.key: d for d in engine.run(operator.truediv, jobs, limit=1)}
    assert done["half"].result == 0.5 and done["half"].error == ""
    assert done["big"].result == 3.0                         # ran on a whole node instead
    assert done["zero"].result is None and "ZeroDivisionError" in done["zero"].error
    assert len({d.node for d in done.values()}) == 1 and len(done["half"].node) == 12


def test_an_address_where_nothing_listens_is_a_clear_error():
    with socket.socket() as s:                               # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(EngineError, match=f"nothing answers at 127.0.0.1:{port}"):
        Engine(f"127.0.0.1:{port}")
    with pytest.raises(EngineError, match="not a Ray address"):
        Engine("my-cluster")


def test_bench_names_address_for_an_unreachable_cluster(tmp_path, capsys):
    code = bench.main(["run", "--scenes", "n1_s0", "--planners", "pc-rrt", "--seeds", "0",
                       "--address", "127.0.0.1:9", "--out", str(tmp_path / "o")])
    assert code == 2
    assert "rearrangement-bench: --address: nothing answers at 127.0.0.1:9" in \
        capsys.readouterr().err


# --------------------------------------------------------------------------------------------
# A real two-node cluster
# --------------------------------------------------------------------------------------------

RAY = Path(sys.executable).with_name("ray")
CLUSTER_ENV = {**os.environ, "RAY_USAGE_STATS_ENABLED": "0", "RAY_worker_niceness": "0",
               "RAY_AUTH_MODE": "disabled"}
"""A throwaway cluster on this machine's loopback for the test's few seconds: no token."""


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _ray_start(*args: str) -> subprocess.Popen:
    """`ray start --block ...` in a process group of its own (the node's processes join it)."""
    return subprocess.Popen([str(RAY), "start", "--block", "--num-cpus", "1",
                             "--disable-usage-stats", *args],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            env=CLUSTER_ENV, start_new_session=True)


def _stop(*procs: subprocess.Popen) -> None:
    """End nodes: SIGTERM to their process groups at once, then SIGKILL to whatever is left."""
    for sig, wait in ((signal.SIGTERM, 3.0), (signal.SIGKILL, 5.0)):
        left = [p for p in procs if p.poll() is None]
        for proc in left:
            try:
                os.killpg(proc.pid, sig)
            except ProcessLookupError:
                pass
        deadline = time.monotonic() + wait
        for proc in left:
            try:
                proc.wait(max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                pass
    for proc in procs:
        try:
            os.killpg(proc.pid, signal.SIGKILL)              # the nodes' children
        except ProcessLookupError:
            pass


def _alive_nodes(address: str) -> int:
    probe = (f"import ray; ray.init(address={address!r}, logging_level='ERROR'); "
             "print(sum(n['Alive'] for n in ray.nodes()))")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                         env=CLUSTER_ENV, timeout=120)
    return int(out.stdout.split()[-1]) if out.returncode == 0 and out.stdout.split() else 0


@pytest.fixture
def two_node_cluster():
    """A head and a worker node, one CPU each: its address."""
    port = _free_port()
    address = f"127.0.0.1:{port}"
    head = _ray_start("--head", "--port", str(port), "--include-dashboard", "false")
    worker = None
    try:
        deadline = time.monotonic() + 120
        while True:
            try:
                socket.create_connection(("127.0.0.1", port), timeout=1).close()
                break
            except OSError:
                assert head.poll() is None, head.stderr.read().decode()
                assert time.monotonic() < deadline, "the head did not start"
                time.sleep(0.5)
        worker = _ray_start("--address", address)
        while _alive_nodes(address) < 2:
            assert worker.poll() is None, worker.stderr.read().decode()
            assert time.monotonic() < deadline, "the worker node did not join"
            time.sleep(1.0)
        yield address
    finally:
        _stop(*(proc for proc in (worker, head) if proc is not None))


def test_a_benchmark_runs_on_both_nodes_of_a_local_cluster(two_node_cluster, tmp_path):
    """Four one-tree trials on two one-CPU nodes: two run at once, one on each node, and every
    row names the node that ran it."""
    out = tmp_path / "bench"
    run = subprocess.run(
        [sys.executable, "-m", "rearrangement_planner.tools.bench.command", "run", "--address",
         two_node_cluster, "--scenes", "n1_s0", "n1_s1", "n2_s0", "n2_s1", "--planners",
         "pc-rrt", "--seeds", "0", "--time-limit", "4", "--set", "min_robustness=0", "--set",
         "trees=1", "--set", "shortcut_time=0", "--perturbed", "0", "--out", str(out)],
        capture_output=True, text=True, env=CLUSTER_ENV, timeout=600)
    assert run.returncode == 0, run.stderr
    assert f"Ray at {two_node_cluster}, as its CPUs take" in run.stderr
    with (out / "trials.csv").open(newline="") as f:
        rows = list(csv.DictReader(f))
    assert sorted(r["scene"] for r in rows) == ["n1_s0", "n1_s1", "n2_s0", "n2_s1"]
    assert len({r["ray_node"] for r in rows}) == 2
    assert all(len(r["ray_node"]) == 12 for r in rows)
