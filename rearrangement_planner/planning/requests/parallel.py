"""OR-parallel planning: several independent trees race on separate processes.

One tree of a sampling-based planner often needs many times the median time to solve (the
clutter scene: 150 to 2800 PC-RRT iterations over seeds). Growing T independent trees at once
and keeping the first plan found is the OR-parallel RRT of Carpin & Pagello ("On parallel RRTs
for multi-robot systems", 2002); with a heavy-tailed solve time it cuts the long tail on a
multi-core machine much more than it costs.

Tree t plans with its own seed `tree_seed(seed, t)`; tree 0 uses `seed` itself and runs in the
calling process, so one tree is exactly the single-process planner. Trees 1 .. T-1 run on
persistent worker processes (spawned once, reused by later plans; a scene's robot model and
physics are built once per worker).

Reproducible: the winner is not the first plan in wall-clock time but the plan with the fewest
iterations, ties going to the lower tree index. Every tree checks before each iteration whether
it could still win (`key(iteration, t) < best key found`) and stops as soon as it cannot, so the
race ends shortly after the first plan, and the same scene, options and seed give the same plan
whatever the machine's speed. The one exception is the time limit: a plan found by one tree
before the budget runs out is returned even if a tree that might have beaten it in iterations
was cut off by the budget (or did not report within `RESULT_GRACE` of it: a worker still
starting on a loaded machine).

    result = plan_race(PLANNERS["pc-rrt"], scene, PCRRTOptions(), trees=2, seed=0)
"""

from __future__ import annotations

import dataclasses
import hashlib
import multiprocessing
import os
import pickle
import threading
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from rearrangement_planner.model.scene import Scene
from rearrangement_planner.model.settings import Settings, setting
from rearrangement_planner.model.state import State
from rearrangement_planner.physics.options import PhysicsOptions
from rearrangement_planner.physics.step import Physics
from rearrangement_planner.planning.machinery.interface import (
    Outcome,
    PlannerOptions,
    PlanResult,
    ProgressCallback,
)
from rearrangement_planner.planning.machinery.termination import Termination
from rearrangement_planner.planning.requests.registry import PlannerSpec


@dataclass(frozen=True)
class RaceOptions(Settings):
    """How many trees a plan request races (`plan_race`)."""

    trees: int = setting(2, low=1, high=64)
    """Independent trees grown at once on separate processes, the plan found in the fewest
    iterations winning (OR-parallel RRT); 1 = one tree in the calling process. The default is
    one per core of the 2-core machines the benchmark runs on."""


NO_PLAN = 2 ** 62
"""The race key before any tree has found a plan."""

RESULT_GRACE = 5.0
"""Seconds past the budget a worker tree gets to report (it stops within one propagation
step of its deadline). A worker that misses it (a fresh one still loading the compiled core on
a loaded machine, or a hung one) is left out of the race's result and waited for by the next
race (`STRAGGLER_WAIT`)."""

STRAGGLER_WAIT = 30.0
"""Seconds the next race waits for a worker still busy with a race it did not report to in
time; one that takes longer is hung: it is terminated and replaced."""

SCENE_CACHE = 4
"""Scenes (robot model + physics) a worker keeps built."""


def tree_seed(seed: int, tree: int) -> int:
    """The seed of tree `tree` of a race planned with `seed`: `seed` itself for tree 0, else a
    hash of (seed, tree) in [0, 2^31) (so `PCRRT(...).plan(seed=tree_seed(s, t))` replays any
    tree on its own)."""
    if tree == 0:
        return seed
    state = np.random.SeedSequence([seed & 0xFFFFFFFF, seed >> 32 & 0xFFFFFFFF, tree])
    return int(state.generate_state(1, dtype=np.uint32)[0] >> 1)


def race_key(iteration: int, tree: int, trees: int) -> int:
    """Order of plans in a race: fewer iterations first, then the lower tree index."""
    return iteration * trees + tree


def _gate(best, tree: int, trees: int) -> Callable[[int], bool]:
    """The planners' `iteration_gate`: may `tree` still start iteration `it` and win?"""
    def gate(it: int) -> bool:
        return race_key(it, tree, trees) < best.value
    return gate


def _claim(best, result: PlanResult, tree: int, trees: int) -> None:
    if result.solved:
        key = race_key(result.iterations, tree, trees)
        with best.get_lock():
            if key < best.value:
                best.value = key


# -- the worker processes ------------------------------------------------------------------------

def _scene_payload(scene: Scene, physics_options: PhysicsOptions) -> tuple[str, bytes]:
    """What a worker needs to rebuild the scene and its physics, and a key to cache it by."""
    robot = scene.robot
    data = scene.to_dict()
    data.pop("robot")
    blob = pickle.dumps((robot.config, robot.urdf_xml, data, scene.source, physics_options))
    return hashlib.sha1(blob).hexdigest(), blob


def _build(blob: bytes) -> tuple[Scene, Physics]:
    from rearrangement_planner.model.robot import RobotModel
    from rearrangement_planner.physics.validation import parse_scene

    config, urdf_xml, data, source, physics_options = pickle.loads(blob)
    scene = parse_scene(data, name=source, robot=RobotModel(config, urdf_xml=urdf_xml))
    return scene, Physics(scene, physics_options)


PARENT_POLL = 0.5
"""Seconds between a tree worker's checks that the process that started it is still there."""


def _exit_with_parent(parent: int) -> None:
    """A tree worker's watch: end the worker when the process that started it is gone (killed
    without the chance to stop it, as a terminated benchmark worker is) instead of planning on
    to its deadline with nobody to report to."""
    while os.getppid() == parent:
        time.sleep(PARENT_POLL)
    os._exit(0)


def _serve(conn, best, cancel, ready) -> None:
    """A worker process: plan one tree per task until the pipe closes. It loads the compiled
    core first (`warm_up`), while the first task is on its way, and then sets `ready`."""
    from rearrangement_planner.planning.requests.warmup import warm_up

    threading.Thread(target=_exit_with_parent, args=(os.getppid(),), daemon=True,
                     name="parent-watch").start()

    warm_up()
    ready.set()
    built: dict[str, tuple[Scene, Physics]] = {}
    while True:
        try:
            task = conn.recv()
        except (EOFError, OSError):
            return
        try:
            key, blob, planner, options, seed, tree, trees, start, budget = task
            if key not in built:
                if len(built) >= SCENE_CACHE:
                    built.pop(next(iter(built)))
                built[key] = _build(blob)
            scene, physics = built[key]
            deadline, max_iterations, time_limit = budget
            stop = Termination(deadline, cancel, max_iterations, _gate(best, tree, trees),
                               time_limit)
            result = planner.make(scene, options, physics).plan(
                start=start, seed=tree_seed(seed, tree), stop=stop)
            _claim(best, result, tree, trees)
            reply: Any = result
        except Exception:           # reported to the caller, which raises it
            reply = traceback.format_exc()
        try:
            conn.send(reply)
        except (BrokenPipeError, OSError):
            return


class _Worker:
    def __init__(self, context, best, cancel):
        self.conn, child = context.Pipe()
        self.ready = context.Event()
        self.process = context.Process(target=_serve, args=(child, best, cancel, self.ready),
                                       daemon=True, name="rearrangement-tree")
        self.process.start()
        child.close()
        self.busy = False

    def collect(self, timeout: float | None) -> PlanResult | str | None:
        """The reply of the running task; None if it does not come within `timeout`."""
        if timeout is not None and not self.conn.poll(max(timeout, 0.0)):
            return None
        try:
            reply = self.conn.recv()
        except (EOFError, OSError):
            reply = f"tree worker process {self.process.pid} died " \
                    f"(exit code {self.process.exitcode})"
            self.process.join(1.0)
            self.busy = False
            raise RuntimeError(reply) from None
        self.busy = False
        return reply


class _Pool:
    """Worker processes and the race's shared state: the best key and the cancel flag."""

    def __init__(self):
        self.context = multiprocessing.get_context("spawn")
        self.best = self.context.Value("q", NO_PLAN)
        self.cancel = self.context.Event()
        self.workers: list[_Worker] = []
        self.lock = threading.Lock()

    def take(self, n: int) -> list[_Worker]:
        """n idle workers (a worker still winding down a cancelled race is waited for)."""
        self.workers = [w for w in self.workers if w.process.is_alive() or w.busy]
        for w in self.workers:
            if w.busy:
                try:
                    if w.collect(STRAGGLER_WAIT) is None:
                        w.process.terminate()
                        w.process.join(1.0)
                        w.busy = False
                except RuntimeError:
                    pass
        self.workers = [w for w in self.workers if w.process.is_alive()]
        while len(self.workers) < n:
            self.workers.append(_Worker(self.context, self.best, self.cancel))
        return self.workers[:n]


_POOL: _Pool | None = None
_POOL_LOCK = threading.Lock()


def _pool() -> _Pool:
    global _POOL
    with _POOL_LOCK:
        if _POOL is None:
            _POOL = _Pool()
        return _POOL


WORKER_START_WAIT = 120.0
"""Seconds `warm_up_race` waits for a fresh worker to load the compiled core (well under two
when the disk cache holds it; a first compile takes about half a minute)."""


READY_POLL = 0.02
"""Seconds between `warm_up_race`'s checks that a starting worker is still alive."""


def start_workers(trees: int) -> list[_Worker]:
    """Start the worker processes a race of `trees` trees needs, if they are not yet running,
    without waiting for them; they load the compiled core on their own (`_serve`). Returns
    them."""
    if trees <= 1:
        return []
    pool = _pool()
    with pool.lock:
        return pool.take(trees - 1)


def warm_up_race(trees: int) -> int:
    """Load the compiled core in this process (`warm_up`) and, at the same time, in the worker
    processes a race of `trees` trees needs (`start_workers`), and wait until they have: a
    plan's clock then holds no worker's start (about 2 s on this machine, which the caller's
    own warm-up now overlaps). Returns the workers ready."""
    from rearrangement_planner.planning.requests.warmup import warm_up

    workers = start_workers(trees)
    warm_up()
    deadline = time.monotonic() + WORKER_START_WAIT
    for w in workers:       # a worker that died starting is not waited for: its race says why
        while (not w.ready.wait(READY_POLL) and w.process.is_alive()
               and time.monotonic() < deadline):
            pass
    return sum(w.ready.is_set() for w in workers)


def shutdown() -> None:
    """Stop the worker processes (they also end with the interpreter)."""
    global _POOL
    with _POOL_LOCK:
        pool, _POOL = _POOL, None
    if pool is None:
        return
    for w in pool.workers:
        w.conn.close()
    for w in pool.workers:
        w.process.join(2.0)
        if w.process.is_alive():
            w.process.terminate()


# -- the race --------------------------------------------------------------------------------------

def plan_race(planner: PlannerSpec, scene: Scene, options: PlannerOptions, trees: int,
              seed: int = 0, start: State | None = None, stop: Termination | None = None,
              progress: ProgressCallback | None = None,
              physics: Physics | None = None) -> PlanResult:
    """Plan with `trees` independent trees (module doc) until `stop` (default the options'
    budget) ends them: every tree shares its deadline and iteration bound, and its cancel
    stops them all. Tree 0 runs here and reports progress; the result is the winning tree's,
    with `plan_time` the race's wall time and the winner named in `message`. Raises
    RuntimeError if a worker fails."""
    t0 = time.monotonic()
    stop = stop if stop is not None else options.termination()
    physics = physics or Physics(scene)
    pool = _pool()
    with pool.lock:
        workers = pool.take(trees - 1)
        pool.cancel.clear()
        pool.best.value = NO_PLAN
        key, blob = _scene_payload(scene, physics.options)
        budget = (stop.deadline, stop.max_iterations, stop.time_limit)
        for t, worker in enumerate(workers, start=1):
            worker.conn.send((key, blob, planner, options, seed, t, trees, start, budget))
            worker.busy = True
        user_cancelled = stop.cancelled

        def stop_all() -> bool:
            if user_cancelled():
                pool.cancel.set()
                return True
            return False

        own_stop = dataclasses.replace(stop, cancel=_Flag(stop_all),
                                       gate=_gate(pool.best, 0, trees))
        try:
            own = planner.make(scene, options, physics).plan(
                start=start, seed=seed, stop=own_stop, progress=progress)
        except BaseException:
            pool.cancel.set()       # do not leave the workers planning to their deadline
            raise
        _claim(pool.best, own, 0, trees)
        if own.outcome is Outcome.CANCELLED and user_cancelled():
            pool.cancel.set()       # the workers stop within a step; `take` waits for them
            return dataclasses.replace(own, plan_time=time.monotonic() - t0)
        results: list[PlanResult] = [own]
        errors: list[str] = []
        for worker in workers:
            reply = worker.collect(stop.remaining() + RESULT_GRACE)
            if reply is None:
                # Its tree did not run within the budget (see RESULT_GRACE): the race ends
                # without it, the cancel stops it at its first check, and the next race waits
                # for it (`_Pool.take`).
                pool.cancel.set()
            elif isinstance(reply, str):
                errors.append(reply)
            else:   # states rebuilt here: read-only arrays, like every State
                results.append(dataclasses.replace(
                    reply, states=tuple(State(s.q, s.objects) for s in reply.states)))
        if errors:
            pool.cancel.set()
            raise RuntimeError("parallel planning failed: " + "\n".join(errors))
    return _outcome(results, seed, trees, time.monotonic() - t0)


class _Flag:
    """A cancel flag whose state is a function (the planners call `is_set()`)."""

    def __init__(self, test: Callable[[], bool]):
        self.is_set = test


def _outcome(results: list[PlanResult], seed: int, trees: int, elapsed: float) -> PlanResult:
    """The race's result: the winning plan, else tree 0's failure with the race's totals."""
    solved = [(race_key(r.iterations, t, trees), t, r)
              for t, r in enumerate(results) if r.solved]
    best_distance = min(r.best_goal_distance for r in results)
    total_steps = sum(r.propagation_steps for r in results)
    if solved:
        _, t, winner = min(solved, key=lambda s: s[0])
        return dataclasses.replace(
            winner, message=f"{winner.message} of tree {t} of {trees} (tree seed {winner.seed})",
            seed=seed, plan_time=elapsed, propagation_steps=total_steps)
    own = results[0]
    if own.outcome in (Outcome.START_INVALID, Outcome.INVALID_INPUT):
        return dataclasses.replace(own, plan_time=elapsed)
    budgets = [r for r in results if r.outcome in (Outcome.TIMEOUT, Outcome.PLANNING_FAILED)]
    ended = budgets[0] if budgets else own
    return dataclasses.replace(
        own, outcome=ended.outcome,
        message=f"{ended.message} ({trees} trees, {sum(r.iterations for r in results)} iterations "
                f"in all)",
        iterations=sum(r.iterations for r in results),
        tree_size=sum(r.tree_size for r in results), propagation_steps=total_steps,
        plan_time=elapsed, best_goal_distance=best_distance)
