"""The search tree shared by PC-RRT and the baselines: nodes in growing arrays, so that Nearest
is one compiled call over them (`Tree.nearest`), and the edge (the propagated states) into each
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
    position). The edge from `parent[i]` to node i, ending at it, is kept as its steps in two
    growing arrays shared by all edges (`path_to` builds States only for a plan's path): a long
    search's million steps as objects took a quarter of a second to free when it ended, past
    its deadline; as two arrays they take nothing."""

    def __init__(self, root: State, root_arm: np.ndarray, capacity: int = 1024):
        self.n = 0
        self.q = np.empty((capacity, root.q.size))
        self.arm = np.empty((capacity, root_arm.size))
        self.objects = np.empty((capacity, *root.objects.shape))
        self.parent = np.empty(capacity, dtype=np.int64)
        # Node i's arrangement (`arrangement[i]`): the objects' poses it shares with every node
        # reached from it without moving an object; `first_node[a]` holds arrangement a,
        # `arrangements[0]` counts them, `distance` is Nearest's scratch (one per arrangement).
        # An arrangement's nodes in the order they were added: from `first_node[a]` along
        # `next_node` (-1 ends it) to `last_node[a]`. `places[c, j, a]` is coordinate c (x, y)
        # of its object j: each object's coordinates of every arrangement side by side, for
        # Nearest's pass over them (`nearest_kernel`).
        self.arrangement = np.empty(capacity, dtype=np.int64)
        self.first_node = np.empty(capacity, dtype=np.int64)
        self.last_node = np.empty(capacity, dtype=np.int64)
        self.next_node = np.empty(capacity, dtype=np.int64)
        self.places = np.empty((2, root.objects.shape[0], capacity))
        self.arrangements = np.zeros(1, dtype=np.int64)
        self.distance = np.empty(capacity)
        self._spans = np.empty((capacity, 2), dtype=np.int64)     # node i's steps: [start, end)
        self._step_q = np.empty((8 * capacity, root.q.size))
        self._step_objects = np.empty((8 * capacity, *root.objects.shape))
        self._steps = 0
        self.add(root, root_arm, -1, ())

    def add(self, state: State, arm: np.ndarray, parent: int,
            segment: tuple[State, ...] | Propagation) -> int:
        """Add a node reached from `parent` along `segment` (its states, or the propagation
        that made it); returns its index."""
        if isinstance(segment, Propagation):
            seg_q, seg_objects = segment.arm, segment.objects
        else:
            seg_q = np.array([s.q for s in segment]).reshape(len(segment), self.q.shape[1])
            seg_objects = np.array([s.objects for s in segment]).reshape(
                len(segment), *self.objects.shape[1:])
        count = len(seg_q)
        self.make_room(count)
        self._step_q[self._steps:self._steps + count] = seg_q
        self._step_objects[self._steps:self._steps + count] = seg_objects
        self._spans[self.n] = self._steps, self._steps + count
        self._steps += count
        self.q[self.n] = state.q
        self.arm[self.n] = arm
        self.objects[self.n] = state.objects
        self.parent[self.n] = parent
        set_arrangement(self.objects, self.nearest_arrays, self.n, parent)
        self.n += 1
        return self.n - 1

    @property
    def arrays(self) -> tuple:
        """The node and step arrays, for compiled code that adds nodes itself
        (`pcrrt_kernel.iterations`): q, arm, objects, parent, spans, step q, step objects,
        and Nearest's (`nearest_arrays`). It reads and sets `n` and `steps` (and the
        arrangements, `set_arrangement`); `make_room` makes room for more first."""
        return (self.q, self.arm, self.objects, self.parent, self._spans, self._step_q,
                self._step_objects, self.nearest_arrays)

    @property
    def nearest_arrays(self) -> tuple[np.ndarray, ...]:
        """What `nearest_kernel` reads besides the nodes' arm features and objects: each node's
        arrangement, each arrangement's first node, their count (1,), Nearest's scratch, each
        arrangement's last node, each node's next in its arrangement and each arrangement's
        objects' positions."""
        return (self.arrangement, self.first_node, self.arrangements, self.distance,
                self.last_node, self.next_node, self.places)

    @property
    def steps(self) -> int:
        """Edge steps held (of all nodes)."""
        return self._steps

    @steps.setter
    def steps(self, value: int) -> None:
        self._steps = value

    def make_room(self, steps: int) -> None:
        """Double the arrays that cannot take one more node of `steps` steps."""
        if self.n == len(self.arm):
            (self.q, self.arm, self.objects, self.parent, self._spans, self.arrangement,
             self.first_node, self.distance, self.last_node, self.next_node) = (
                _doubled(a) for a in (self.q, self.arm, self.objects, self.parent, self._spans,
                                      self.arrangement, self.first_node, self.distance,
                                      self.last_node, self.next_node))
            self.places = np.concatenate([self.places, np.empty_like(self.places)], axis=2)
        while self._steps + steps > len(self._step_q):
            self._step_q, self._step_objects = _doubled(self._step_q), _doubled(
                self._step_objects)

    def nearest(self, arm: np.ndarray, objects: np.ndarray, arm_weight: float,
                weights: np.ndarray) -> int:
        """Nearest (King et al. 2015, §III-D): the node closest to (arm, objects) by
        Dist = arm_weight |arm_i - arm| + sum_j weights[j] |o_i^j - o^j| (object positions in
        the plane). One compiled call (`nearest_kernel`; NumPy's temporaries took half of a
        long plan's time)."""
        # Fresh writable copies: one compiled signature whoever calls.
        return int(nearest_kernel(self.arm, self.n, self.nearest_arrays,
                                  np.array(arm, dtype=float), np.array(objects, dtype=float),
                                  float(arm_weight), np.array(weights, dtype=float)))

    def state(self, node: int) -> State:
        return State(self.q[node], self.objects[node])

    def path_to(self, node: int, root: State) -> list[State]:
        """Every state from the root to `node`, the root first."""
        pieces = []
        while node > 0:
            pieces.append(self._spans[node])
            node = int(self.parent[node])
        states = [root]
        for start, end in reversed(pieces):
            states.extend(State.rows(self._step_q[start:end].copy(),
                                     self._step_objects[start:end].copy()))
        return states


def weighted_distance(arm: np.ndarray, objects: np.ndarray, sample_arm: np.ndarray,
                      sample_objects: np.ndarray, arm_weight: float,
                      weights: np.ndarray) -> float:
    """Dist of `Tree.nearest` between one state and a sample, compiled (NumPy's temporaries
    cost more than the sum)."""
    # Fresh writable copies: one compiled signature whoever calls.
    return float(metric(np.array(arm, dtype=float), np.array(objects, dtype=float),
                         np.array(sample_arm, dtype=float),
                         np.array(sample_objects, dtype=float), float(arm_weight),
                         np.array(weights, dtype=float)))


@njit(cache=True, inline="always")
def metric(arm: np.ndarray, objects: np.ndarray, sample_arm: np.ndarray,
           sample_objects: np.ndarray, arm_weight: float, weights: np.ndarray) -> float:
    """Dist (King et al. 2015, §III-D): arm_weight |arm - arm'| + sum_j weights[j] |o^j - o'^j|
    (object positions in the plane)."""
    return (arm_weight * _arm_distance(arm, sample_arm)
            + _objects_distance(objects, sample_objects, weights))


@njit(cache=True, inline="always")
def _arm_distance(arm: np.ndarray, sample_arm: np.ndarray) -> float:
    """|arm - arm'| of `metric`."""
    d_arm = 0.0
    for k in range(arm.shape[0]):
        d = arm[k] - sample_arm[k]
        d_arm += d * d
    return math.sqrt(d_arm)


@njit(cache=True, inline="always")
def _objects_distance(objects: np.ndarray, sample_objects: np.ndarray,
                      weights: np.ndarray) -> float:
    """sum_j weights[j] |o^j - o'^j| of `metric`."""
    d_obj = 0.0
    for j in range(weights.shape[0]):
        dx, dy = objects[j, 0] - sample_objects[j, 0], objects[j, 1] - sample_objects[j, 1]
        d_obj += weights[j] * math.sqrt(dx * dx + dy * dy)
    return d_obj


def _doubled(a: np.ndarray) -> np.ndarray:
    return np.concatenate([a, np.empty_like(a)])


@njit(cache=True)
def nearest_kernel(arms: np.ndarray, n: int, arrays: tuple, arm: np.ndarray,
                   sample: np.ndarray, arm_weight: float, weights: np.ndarray) -> int:
    """The node of the first n nearest (arm, sample) by `metric` (the first of equals).

    Most edges move no object (the arm travels, or its push misses), so most nodes share their
    objects' poses with others: the nodes of 10,000 iterations on four varied scenes held a
    twentieth to a fifth as many arrangements (`Tree.nearest_arrays`, `set_arrangement`).
    The objects' term is summed once per arrangement, object by object over all of them at
    once (`_add_object_term`), and each node of an arrangement adds its arm's to it. No node
    is nearer than its arrangement's objects' term, so only arrangements whose term is no
    larger than the best distance found so far are scanned, the one of least term first
    (docs/experiments.md, "Nearest skips far arrangements"). The same sums as `metric` node by
    node, and the same node: the least (distance, index)."""
    arrangement, first_node, arrangements, distance, last_node, next_node, places = arrays
    count = arrangements[0]
    distance[:count] = 0.0
    for j in range(weights.shape[0]):       # object by object: each sum in `metric`'s order
        _add_object_term(places[0, j], places[1, j], sample[j, 0], sample[j, 1], weights[j],
                         distance[:count])
    least = 0
    for a in range(count):
        if distance[a] < distance[least]:
            least = a
    best, best_node = _nearest_of(arms, n, first_node[least], next_node, distance[least], arm,
                                  arm_weight, math.inf, 0)
    for a in range(count):
        if a != least and distance[a] <= best:
            best, best_node = _nearest_of(arms, n, first_node[a], next_node, distance[a], arm,
                                          arm_weight, best, best_node)
    return best_node


@njit(cache=True, inline="always")
def _add_object_term(xs: np.ndarray, ys: np.ndarray, x: float, y: float, weight: float,
                     distance: np.ndarray) -> None:
    """Add one object's term of `metric` to every arrangement's sum (a loop the compiler
    runs several arrangements at a time)."""
    for a in range(distance.shape[0]):
        dx, dy = xs[a] - x, ys[a] - y
        distance[a] += weight * math.sqrt(dx * dx + dy * dy)


@njit(cache=True, inline="always")
def _nearest_of(arms: np.ndarray, n: int, node: int, next_node: np.ndarray,
                objects_term: float, arm: np.ndarray, arm_weight: float, best: float,
                best_node: int) -> tuple[float, int]:
    """The least (distance, node) of (best, best_node) and an arrangement's nodes below n,
    from `node` along `next_node`, whose objects' term is `objects_term`."""
    while 0 <= node < n:
        total = arm_weight * _arm_distance(arms[node], arm) + objects_term
        if total < best or (total == best and node < best_node):
            best, best_node = total, node
        node = next_node[node]
    return best, best_node


@njit(cache=True)
def set_arrangement(objects: np.ndarray, arrays: tuple, node: int, parent: int) -> None:
    """Give the new node its arrangement (`Tree.nearest_arrays`): its parent's, where its
    objects' poses equal the parent's entry by entry, else a new one that it holds first; it
    is its arrangement's last node."""
    arrangement, first_node, arrangements, _, last_node, next_node, places = arrays
    next_node[node] = -1
    if parent >= 0:
        same = True
        for j in range(objects.shape[1]):
            for c in range(objects.shape[2]):
                same = same and objects[node, j, c] == objects[parent, j, c]
        if same:
            a = arrangement[parent]
            arrangement[node] = a
            next_node[last_node[a]] = node
            last_node[a] = node
            return
    a = arrangements[0]
    arrangement[node], first_node[a], last_node[a] = a, node, node
    places[0, :, a], places[1, :, a] = objects[node, :, 0], objects[node, :, 1]
    arrangements[0] = a + 1
