"""A controller command: what a joint trajectory controller given positions only plays, the
positions interpolated linearly in time between the points. The planner's quasistatic
executions (`execution.open_loop`) and the 3D world's (`world3d.execution`) both play it."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Command:
    """A checked controller command: `times` (N,) s, strictly increasing from 0, and
    `positions` (N, n) rad in the robot's planning-joint order; linear interpolation between
    the points (a joint trajectory controller given positions only)."""

    times: np.ndarray
    positions: np.ndarray

    @property
    def duration(self) -> float:
        return float(self.times[-1])

    def sample(self, t: float) -> np.ndarray:
        """Positions at trajectory time t (s), clamped to the first/last point."""
        if t <= 0.0:
            return self.positions[0].copy()
        if t >= self.duration:
            return self.positions[-1].copy()
        i = int(np.searchsorted(self.times, t, side="right")) - 1
        alpha = (t - self.times[i]) / (self.times[i + 1] - self.times[i])
        return (1.0 - alpha) * self.positions[i] + alpha * self.positions[i + 1]

    def velocity(self, t: float) -> np.ndarray:
        """The slope of the segment at time t (rad/s of trajectory time); zero outside."""
        if t < 0.0 or t >= self.duration:
            return np.zeros(self.positions.shape[1])
        i = int(np.searchsorted(self.times, t, side="right")) - 1
        return (self.positions[i + 1] - self.positions[i]) / (self.times[i + 1] - self.times[i])
