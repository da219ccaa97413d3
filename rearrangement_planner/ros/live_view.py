"""The node's live view (parameter live_view_port; `io.live`): the planning scene at each
request, the search while it runs, the answer, and each execution of the closed loop, the
observed objects beside their predicted poses, with every attempt's outcome in the log.

    live = NodeLive.open(port, scene, logger)    # does nothing when the port is 0
    live.search(progress); live.answer(scene, output); live.log(summary)
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rearrangement_planner.io.live import LiveView, LiveViewError
from rearrangement_planner.model.scene import Scene


class NodeLive:
    """The live view of one node; every method does nothing when it is off."""

    def __init__(self, view: LiveView | None, scene: Scene):
        self.view, self.scene = view, scene

    @classmethod
    def open(cls, port: int, scene: Scene, logger: Any) -> NodeLive:
        """Start the server on `port` (the node's live_view_port; 0: off) showing `scene`. A
        port that cannot be served is logged, and the node goes on without the view."""
        if port == 0:
            return cls(None, scene)
        try:
            view = LiveView(port)
        except LiveViewError as exc:
            logger.error(f"{exc}; the node runs without it")
            return cls(None, scene)
        logger.info(f"live view on {view.url}: in Foxglove, Open connection and give that "
                    f"address (layout: config/foxglove_layout.json)")
        view.scene(scene)
        return cls(view, scene)

    def search(self, progress: Any) -> None:
        if self.view is not None:
            self.view.search(self.scene, progress)

    def answer(self, scene: Scene, output: Any) -> None:
        """A request's planning scene (the arm where it starts) and its answer."""
        if self.view is None:
            return
        self.scene = scene
        self.view.scene(scene)
        if output is not None:
            self.view.answer(output)

    def executing(self, q: np.ndarray, observed: np.ndarray | None,
                  predicted: np.ndarray) -> None:
        """The arm and the objects now, during an execution the watch follows."""
        if self.view is not None:
            self.view.execution(self.scene, q, observed, predicted)

    def log(self, text: str) -> None:
        if self.view is not None:
            self.view.log(text)

    def close(self) -> None:
        if self.view is not None:
            self.view.close()
