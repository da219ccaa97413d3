"""The planning state x = (q, o^1 ... o^M) of King et al. 2015, §II-A: the arm configuration and the
planar pose (x, y, yaw) of every movable object, in the base frame (m, rad)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class State:
    q: np.ndarray        # (nq,) joint positions, rad
    objects: np.ndarray  # (M, 3) object poses (x, y, yaw) in the base frame

    def __post_init__(self) -> None:
        q = np.array(self.q, dtype=float)
        objects = np.array(self.objects, dtype=float).reshape(-1, 3)
        q.setflags(write=False)
        objects.setflags(write=False)
        object.__setattr__(self, "q", q)
        object.__setattr__(self, "objects", objects)

    @classmethod
    def trusted(cls, q: np.ndarray, objects: np.ndarray) -> State:
        """A state from float arrays of the right shapes that nobody else holds (no copies; the
        physics step's hot path). They become read-only."""
        state = object.__new__(cls)
        q.setflags(write=False)
        objects.setflags(write=False)
        object.__setattr__(state, "q", q)
        object.__setattr__(state, "objects", objects)
        return state

    @classmethod
    def rows(cls, arm: np.ndarray, objects: np.ndarray) -> list[State]:
        """One state per row of `arm` (K, nq) and `objects` (K, M, 3), float arrays that nobody
        else holds (`trusted`), each state's arrays views of them. They become read-only
        whole, and so are their rows: a replay's states cost a third of what `trusted` per row
        costs (`rearrangement-bench physics`)."""
        arm.setflags(write=False)
        objects.setflags(write=False)
        new = object.__new__
        states = []
        for q, poses in zip(arm, objects, strict=True):
            state = new(cls)
            fields = state.__dict__
            fields["q"], fields["objects"] = q, poses
            states.append(state)
        return states

    def with_q(self, q: np.ndarray) -> State:
        return State(q, self.objects)

    def with_objects(self, objects: np.ndarray) -> State:
        return State(self.q, objects)

    def equals(self, other: State, atol: float = 0.0) -> bool:
        return bool(np.allclose(self.q, other.q, atol=atol, rtol=0)
                    and np.allclose(self.objects, other.objects, atol=atol, rtol=0))


def wrap_angle(a: np.ndarray | float) -> np.ndarray | float:
    """Wrap angles to [-pi, pi)."""
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi
