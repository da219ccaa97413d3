"""The benchmarks' execution engine: every trial a Ray task (https://docs.ray.io).

`Engine(address)` connects once per process. Without an address it starts an embedded local
Ray with this machine's cores: nothing to set up, and it ends with the process. With an address
(`HOST:PORT` as `ray start --head` prints it) it joins that cluster, whose nodes may be other
machines or other `ray start --address` processes on this one; every node must have this
package installed in the same Python (a task imports it by name).

`Engine.run(fn, jobs)` runs `fn(*job.args)` for each job as a task that asks for `job.cpus` CPUs
(a plan request that races two trees needs two), at most `limit` at once (the `--workers` of a
local run; None leaves it to the cluster's CPUs), and yields each job's `Done` as it finishes, in
the order they finish, so that the caller writes it to disk at once: an interrupted run loses no
finished trial. A task that raises reports its traceback instead of a result; a task whose
worker dies (killed, out of memory) is reported the same way and not retried, because trials
are deterministic and a retry would fail the same way. Ctrl-C in the caller cancels every task
still running (their worker processes are killed) before the KeyboardInterrupt goes on.

Ray runs its workers at niceness 15 by default. The embedded Ray runs them at 0
(`RAY_worker_niceness`), so that a trial's plan time is what a plain process measures on a
machine that also runs other work; start a cluster's nodes with `RAY_worker_niceness=0` for the
same.

`Progress` is the run's progress bar (tqdm, on stderr): trials done, failed and left, solved,
elapsed time and the time left.
"""

from __future__ import annotations

import logging
import os
import socket
import sys
import time
import traceback
from collections.abc import Callable, Hashable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

ENV = {"RAY_worker_niceness": "0", "RAY_USAGE_STATS_ENABLED": "0"}
"""The environment of an embedded Ray (setdefault: a value the user set wins): workers not
niced, no usage statistics sent."""
QUIET = "ray._private.authentication.authentication_token_setup"
"""The logger of Ray's notice, at every start of a local Ray, that it enabled token
authentication (its default, which the embedded Ray keeps)."""
OBJECT_STORE_BYTES = 128 * 2**20
"""The embedded Ray's shared-memory object store: tasks pass scene paths and CSV rows, not
arrays, so the smallest store Ray accepts suffices."""
CONNECT_S = 5.0
"""How long a cluster's address may take to accept a connection."""
WAIT_S = 0.5
"""How often the run loop wakes up to redraw the progress bar while no task finishes."""


@dataclass(frozen=True)
class Job:
    """One task: `args` for the function, the CPUs it occupies, a label for messages."""

    key: Hashable
    args: tuple
    cpus: int = 1
    label: str = ""


@dataclass(frozen=True)
class Done:
    """A finished job: its result, or the traceback of its failure (`error`), and the Ray node
    it ran on (the node id's first 12 hex digits)."""

    job: Job
    result: Any
    error: str
    node: str


def _call(fn: Callable, args: tuple) -> tuple[Any, str, str]:
    """The task body: (result, "", node) or (None, traceback, node)."""
    import ray

    node = ray.get_runtime_context().get_node_id()[:12]
    try:
        return fn(*args), "", node
    except Exception:   # reported by the caller; one failing trial does not stop the run
        return None, traceback.format_exc(), node


class EngineError(RuntimeError):
    """The cluster cannot be reached or cannot run a task."""


class Engine:
    """A connection to Ray: embedded (`address` None) or an existing cluster."""

    def __init__(self, address: str | None = None):
        import ray

        global _CONNECTED
        if ray.is_initialized():
            if _CONNECTED == (address,):
                return
            ray.shutdown()
        if address is None:
            for name, value in ENV.items():
                os.environ.setdefault(name, value)
        else:
            _check_reachable(address)
        logging.getLogger(QUIET).setLevel(logging.ERROR)
        try:
            ray.init(address="local" if address is None else address,
                     num_cpus=_usable_cores() if address is None else None,
                     object_store_memory=OBJECT_STORE_BYTES if address is None else None,
                     include_dashboard=False, log_to_driver=False,
                     logging_level=logging.WARNING)
        except (ConnectionError, RuntimeError, ValueError) as exc:
            raise EngineError(f"cannot connect to the Ray cluster at {address}: {exc}") \
                from None
        _CONNECTED = (address,)

    @staticmethod
    def node_cpus() -> int:
        """The most CPUs one alive node has (a task cannot span nodes)."""
        import ray

        cpus = [n["Resources"].get("CPU", 0) for n in ray.nodes() if n["Alive"]]
        return int(max(cpus, default=0))

    def run(self, fn: Callable, jobs: Sequence[Job], limit: int | None = None,
            tick: Callable[[], None] = lambda: None) -> Iterator[Done]:
        """Run `fn(*job.args)` for every job (module doc); yields each `Done` as it finishes
        and calls `tick` while none does. A job asking for more CPUs than any node has gets
        all of one node's."""
        import ray

        largest = self.node_cpus()
        if largest < 1:
            raise EngineError("the Ray cluster has no node with a CPU")
        remote = ray.remote(max_retries=0)(_call)
        queue = list(jobs)[::-1]
        running: dict[Any, Job] = {}
        try:
            while queue or running:
                while queue and (limit is None or len(running) < limit):
                    job = queue.pop()
                    ref = remote.options(num_cpus=min(job.cpus, largest)).remote(fn, job.args)
                    running[ref] = job
                ready, _ = ray.wait(list(running), num_returns=1, timeout=WAIT_S)
                if not ready:
                    tick()
                    continue
                job = running.pop(ready[0])
                try:
                    result, error, node = ray.get(ready[0])
                except ray.exceptions.RayError as exc:           # the worker died
                    result, error, node = None, f"{type(exc).__name__}: {exc}", ""
                yield Done(job, result, error, node)
        finally:
            for ref in running:                # Ctrl-C, or the caller stopped iterating
                ray.cancel(ref, force=True)


_CONNECTED: tuple[str | None] | None = None
"""(address,) of the Ray this process is connected to (the embedded one: (None,))."""


def _check_reachable(address: str) -> None:
    """EngineError unless something listens at a HOST:PORT address (Ray itself would retry
    for a minute before it gives up)."""
    host, colon, port = address.rpartition(":")
    if not colon or not host or not port.isdigit():
        raise EngineError(f"{address!r} is not a Ray address HOST:PORT (as `ray start --head` "
                          f"prints it)")
    try:
        socket.create_connection((host, int(port)), timeout=CONNECT_S).close()
    except OSError as exc:
        raise EngineError(f"nothing answers at {address} ({exc.strerror or exc}); start the "
                          f"cluster with `ray start --head --port {port}` or drop --address "
                          f"for the embedded Ray") from None


def _usable_cores() -> int:
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


class Progress:
    """The run's progress bar on `stream` (stderr): a bar redrawn in place on a terminal, and
    one line per finished trial (with its label) everywhere."""

    def __init__(self, total: int, stream=None, unit: str = "trials"):
        from tqdm import tqdm

        self.stream = stream or sys.stderr
        self.t0 = time.monotonic()
        self.total = total
        self.done = self.failed = self.solved = 0
        self.unit = unit
        tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.bar = tqdm(total=total, file=self.stream, unit=unit[:-1], dynamic_ncols=True,
                        disable=not tty, bar_format="{l_bar}{bar}| {n_fmt}/{total_fmt} "
                        "[{elapsed}<{remaining}] {postfix}")
        self._postfix()

    def _postfix(self) -> None:
        self.bar.set_postfix_str(self.counts(), refresh=False)

    def counts(self) -> str:
        left = self.total - self.done - self.failed
        return f"{self.solved} solved, {self.failed} failed, {left} left"

    def advance(self, solved: bool, label: str, failed: bool = False) -> None:
        """One more finished (or failed) job."""
        self.failed += int(failed)
        self.done += int(not failed)
        self.solved += int(solved and not failed)
        self._postfix()
        self.bar.update(1)
        elapsed = time.monotonic() - self.t0
        finished = self.done + self.failed
        eta = elapsed / finished * (self.total - finished) if finished else 0.0
        line = (f"{finished}/{self.total} {self.unit}, {self.counts()}, "
                f"{_duration(elapsed)} elapsed, ~{_duration(eta)} left  {label}")
        if self.bar.disable:
            print(line, file=self.stream, flush=True)
        else:
            self.bar.write(line, file=self.stream)

    def tick(self) -> None:
        self.bar.refresh()

    def close(self) -> None:
        self.bar.close()


def _duration(seconds: float) -> str:
    seconds = int(seconds)
    if seconds < 60:
        return f"{seconds}s"
    if seconds < 3600:
        return f"{seconds // 60}m{seconds % 60:02d}s"
    return f"{seconds // 3600}h{seconds // 60 % 60:02d}m"
