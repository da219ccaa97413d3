"""The search tree shared by PC-RRT and the baselines: nodes in growing arrays, so that Nearest
is one compiled pass over them (`Tree.nearest`), and the edge (the propagated states) into each
node."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from rearrangement_planner.model.state import State
from rearrangement_planner.planning.machinery.propagation import Propagation


class Tree:
    """Nodes of an RRT over full states x = (q, o^1 ... o^M).

    `arm[i]` is what the metric compares of node i's arm (its joint vector, or its tool
    position); `segments[i]` the edge from `parent[i]` to node i, ending at it: its states, or
    the propagation that made it (its states are built only for the plan's path)."""

    def __init__(self, root: State, root_arm: np.ndarray, capacity: int = 1024):
        self.n = 0
        self.q = np.empty((capacity, root.q.size))
        self.arm = np.empty((capacity, root_arm.size))
        self.objects = np.empty((capacity, *root.objects.shape))
        self.parent: list[int] = []
        self.segments: list[tuple[State, ...] | Propagation] = []
        self.add(root, root_arm, -1, ())

    def add(self, state: State, arm: np.ndarray, parent: int,
            segment: tuple[State, ...] | Propagation) -> int:
        """Add a node reached from `parent` along `segment`; returns its index."""
        if self.n == len(self.arm):
            self.q = np.concatenate([self.q, np.empty_like(self.q)])
            self.arm = np.concatenate([self.arm, np.empty_like(self.arm)])
            self.objects = np.concatenate([self.objects, np.empty_like(self.objects)])
        self.q[self.n] = state.q
        self.arm[self.n] = arm
        self.objects[self.n] = state.objects
        self.parent.append(parent)
        self.segments.append(segment)
        self.n += 1
        return self.n - 1

    def nearest(self, arm: np.ndarray, objects: np.ndarray, arm_weight: float,
                weights: np.ndarray) -> int:
        """Nearest (King et al. 2015, §III-D): the node closest to (arm, objects) by
        Dist = arm_weight |arm_i - arm| + sum_j weights[j] |o_i^j - o^j| (object positions in
        the plane). One compiled pass: a tree of 20,000 nodes is scanned in well under a
        millisecond (NumPy's temporaries took half of a long plan's time)."""
        # Fresh writable copies: one compiled signature whoever calls.
        return int(_nearest(self.arm, self.objects, self.n, np.array(arm, dtype=float),
                            np.array(objects, dtype=float), float(arm_weight),
                            np.array(weights, dtype=float)))

    def state(self, node: int) -> State:
        return State(self.q[node], self.objects[node])

    def path_to(self, node: int, root: State) -> list[State]:
        """Every state from the root to `node`, the root first."""
        pieces = []
        while node > 0:
            pieces.append(self.segments[node])
            node = self.parent[node]
        states = [root]
        for piece in reversed(pieces):
            states.extend(piece.states if isinstance(piece, Propagation) else piece)
        return states


@njit(cache=True)
def _nearest(arms: np.ndarray, objects: np.ndarray, n: int, arm: np.ndarray,
             sample: np.ndarray, arm_weight: float, weights: np.ndarray) -> int:
    best, best_node = math.inf, 0
    for i in range(n):
        d_arm = 0.0
        for k in range(arm.shape[0]):
            d = arms[i, k] - arm[k]
            d_arm += d * d
        d_obj = 0.0
        for j in range(weights.shape[0]):
            dx, dy = objects[i, j, 0] - sample[j, 0], objects[i, j, 1] - sample[j, 1]
            d_obj += weights[j] * math.sqrt(dx * dx + dy * dy)
        total = arm_weight * math.sqrt(d_arm) + d_obj
        if total < best:
            best, best_node = total, i
    return best_node
