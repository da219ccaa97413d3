"""The live view (docs/design.md, "Live view"): a Foxglove WebSocket server (`foxglove-sdk`) that
streams the scene in 3D, the search while it runs, the answer, and the execution with the
closed loop, for a user with no ROS install and no RViz. Open Foxglove, "Open connection", and
give the printed address (ws://127.0.0.1:8765 by default); `config/foxglove_layout.json` is a
layout with the 3D panel and the log.

    live = LiveView(8765)
    live.scene(scene)                            # /scene: table, obstacles, objects, goal, arm
    plan_scene(request, progress=live.progress_of(scene))      # /search, at most SEARCH_RATE
    live.answer(output)                          # /plan: predicted paths and objects; /log
    live.execution(scene, q, observed, predicted, "attempt 1: reached")   # /execution
    live.close()

Topics (all `foxglove.SceneUpdate` but /log, a `foxglove.Log`): /scene, /search, /plan,
/execution, /log. A client that subscribes to a topic gets its last update at once, so one that
connects mid-request sees the scene. Nothing is built while no client is subscribed
(`Channel.has_sinks`), so planning costs the same with the view on and nobody watching.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

import foxglove
import numpy as np
from foxglove import messages as fg
from foxglove.channels import LogChannel, SceneUpdateChannel

from rearrangement_planner.io import scene3d
from rearrangement_planner.model.errors import RearrangementError
from rearrangement_planner.model.scene import Scene

DEFAULT_PORT = 8765
"""Foxglove's default connection address is ws://localhost:8765."""
SEARCH_RATE = 4.0
"""Hz: the most search updates a second."""
TOPICS = ("scene", "search", "plan", "execution")


class LiveViewError(RearrangementError):
    """The live view's server could not start (the port is taken, say)."""


class LiveView:
    """One live view server and its channels (module doc)."""

    def __init__(self, port: int = DEFAULT_PORT, host: str = "127.0.0.1"):
        self.context = foxglove.Context()
        self.channels = {topic: SceneUpdateChannel(f"/{topic}", context=self.context)
                         for topic in TOPICS}
        self.log_channel = LogChannel("/log", context=self.context)
        self._last: dict[str, fg.SceneUpdate] = {}
        self._lock = threading.Lock()
        self._next_search = 0.0
        try:
            self.server = foxglove.start_server(name="rearrangement_planner", host=host,
                                                port=port, context=self.context,
                                                server_listener=_Replay(self))
        except Exception as exc:  # noqa: BLE001 - the SDK raises its own error types
            raise LiveViewError(f"the live view cannot serve on {host}:{port}: {exc}") from None
        self.host = host

    @property
    def port(self) -> int:
        return int(self.server.port)

    @property
    def url(self) -> str:
        return f"ws://{self.host}:{self.port}"

    def watched(self, topic: str) -> bool:
        """Whether a client is subscribed to `topic`."""
        return bool(self.channels[topic].has_sinks())

    def send(self, topic: str, update: fg.SceneUpdate) -> None:
        with self._lock:
            self._last[topic] = update
        self.channels[topic].log(update)

    def log(self, text: str, level: fg.LogLevel = fg.LogLevel.Info) -> None:
        now = time.time_ns()
        self.log_channel.log(fg.Log(timestamp=fg.Timestamp(now // 10**9, now % 10**9),
                                    level=level, message=text, name="rearrangement_planner"))

    # -- what is shown --

    def scene(self, scene: Scene, q: np.ndarray | None = None) -> None:
        """The scene at its start (or with the arm at `q`); the search and the answer of an
        earlier request are cleared."""
        self.send("scene", scene3d.scene_update(scene, q))
        clear = fg.SceneUpdate(deletions=[fg.SceneEntityDeletion(
            type=fg.SceneEntityDeletionType.All)])
        for topic in ("search", "plan", "execution"):
            with self._lock:
                self._last.pop(topic, None)
            self.channels[topic].log(clear)

    def progress_of(self, scene: Scene,
                    then: Callable[[Any], None] | None = None) -> Callable[[Any], None]:
        """A planner's progress callback that shows the search (and calls `then`, another
        progress callback, with every report)."""
        def progress(report: Any) -> None:
            self.search(scene, report)
            if then is not None:
                then(report)
        return progress

    def search(self, scene: Scene, report: Any) -> None:
        """The search of a `Progress` report: the goal object's positions over the tree (when
        the report carries them), the best node, the iteration count; at most SEARCH_RATE
        times a second, and only while a client watches."""
        now = time.monotonic()
        if now < self._next_search or not self.watched("search"):
            return
        self._next_search = now + 1.0 / SEARCH_RATE
        positions = (report.goal_positions() if getattr(report, "goal_positions", None)
                     is not None else np.zeros((0, 2)))
        best = None
        if len(positions):
            best = positions[int(np.argmin(np.linalg.norm(
                positions - np.asarray(scene.goal.position), axis=1)))]
        self.send("search", scene3d.search_update(scene, positions, best, report.iterations))

    def answer(self, output: Any) -> None:
        """A request's answer (`PlanOutput`): the predicted object paths and tool path, the
        objects where the plan leaves them, and a log line."""
        scene = output.scene
        if output.trajectory is None:
            self.log(f"no plan: {output.result.outcome.value}: {output.result.message}",
                     fg.LogLevel.Warning)
            return
        objects = np.array([s.objects for s in output.trajectory_states])
        tool = np.array([scene.robot.tool_pose(q)[:3, 3] for q in output.trajectory.positions])
        self.send("plan", fg.SceneUpdate(entities=scene3d.paths_entities(scene, objects, tool)
                                         + scene3d.object_entities(scene, objects[-1],
                                                                   "plan/end", _faded(scene))))
        judged = getattr(output, "judged", None)
        self.log(f"plan: {output.result.outcome.value} in {output.result.plan_time:.2f} s, "
                 f"robustness {output.robustness}"
                 + (f", judged in 3D: {'reached' if judged.reached else judged.failure}"
                    if judged is not None else ""))

    def execution(self, scene: Scene, q: np.ndarray, observed: np.ndarray | None,
                  predicted: np.ndarray | None = None, note: str = "") -> None:
        """The execution now: the arm at `q`, the objects where they are observed (`observed`,
        (M, 3)) and, when given, where the plan predicts them (`predicted`); `note` (an
        attempt's outcome, where the watch stopped the arm) to the log."""
        if note:
            self.log(note)
        if not self.watched("execution"):
            return
        entities = [scene3d.arm_entity(scene, q)]
        if observed is not None:
            entities += scene3d.object_entities(scene, observed, "observed",
                                                [scene3d.OBSERVED] * len(scene.objects))
        if predicted is not None:
            entities += scene3d.object_entities(scene, predicted, "predicted", _faded(scene))
        self.send("execution", fg.SceneUpdate(entities=entities))

    def close(self) -> None:
        self.server.stop()


def _faded(scene: Scene) -> list[tuple[float, float, float, float]]:
    return [(r, g, b, 0.35) for r, g, b, _ in (scene3d.GOAL_OBJECT if i == scene.goal_index
                                               else scene3d.OBJECT
                                               for i in range(len(scene.objects)))]


class _Replay(foxglove.ServerListener):
    """Sends a new subscriber the last update of its topic."""

    def __init__(self, live: LiveView):
        self.live = live

    def on_subscribe(self, client: Any, channel: Any) -> None:
        topic = channel.topic.lstrip("/")
        with self.live._lock:
            update = self.live._last.get(topic)
        if update is not None:
            self.live.channels[topic].log(update)
