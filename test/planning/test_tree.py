"""The search tree's Nearest (`planning.machinery.tree`)."""

from __future__ import annotations

import math

import numpy as np

from rearrangement_planner.model.state import State
from rearrangement_planner.planning.machinery.tree import Tree, nearest_kernel, weighted_distance


def _written_out(arm_i, objects_i, arm, objects, arm_weight, weights) -> float:
    return arm_weight * math.sqrt(float(np.sum((arm_i - arm) ** 2))) + sum(
        weights[j] * math.hypot(*(objects_i[j, :2] - objects[j, :2]))
        for j in range(len(weights)))


def _brute_force(tree: Tree, arm, objects, arm_weight, weights) -> int:
    best, best_node = math.inf, 0
    for i in range(tree.n):
        total = _written_out(tree.arm[i], tree.objects[i], arm, objects, arm_weight, weights)
        if total < best:
            best, best_node = total, i
    return best_node


def arrangements_hold(tree: Tree) -> int:
    """Assert that every node's arrangement holds its objects' poses and is its parent's when
    the two nodes' objects are equal, and that each arrangement's list (from its first node
    along `next_node` to its last) is its nodes in the order they were added, with its
    objects' positions; returns the number of arrangements."""
    count = int(tree.arrangements[0])
    for i in range(tree.n):
        a = int(tree.arrangement[i])
        assert 0 <= a < count
        np.testing.assert_array_equal(tree.objects[tree.first_node[a]], tree.objects[i])
        parent = int(tree.parent[i])
        if parent >= 0 and np.array_equal(tree.objects[parent], tree.objects[i]):
            assert tree.arrangement[parent] == a
    for a in range(count):
        listed = [int(tree.first_node[a])]
        while tree.next_node[listed[-1]] >= 0:
            listed.append(int(tree.next_node[listed[-1]]))
        assert listed == np.flatnonzero(tree.arrangement[:tree.n] == a).tolist()
        assert listed[-1] == tree.last_node[a]
        np.testing.assert_array_equal(tree.places[:, :, a].T,
                                      tree.objects[tree.first_node[a], :, :2])
    return count


def test_nearest_is_the_node_of_least_weighted_distance_ties_to_the_first():
    """The compiled scan against the metric written out (King et al. 2015, §III-D), over
    random trees with a repeated node for a tie (the first wins). Most nodes keep their
    parent's objects, as an edge that moves none does: Nearest sums the objects' term once per
    arrangement and still finds the node the metric does."""
    rng = np.random.default_rng(0)
    for trial in range(20):
        m = 1 + trial % 4
        root = State(rng.uniform(-1, 1, 7), rng.uniform(0, 1, (m, 3)))
        tree = Tree(root, rng.uniform(0, 1, 2), capacity=8)
        for _ in range(300):
            parent = int(rng.integers(0, tree.n))
            objects = (tree.objects[parent].copy() if rng.random() < 0.7
                       else rng.uniform(0, 1, (m, 3)))
            tree.add(State(rng.uniform(-1, 1, 7), objects), rng.uniform(0, 1, 2), parent, ())
        tree.add(tree.state(17), tree.arm[17].copy(), 0, ())          # a tie with node 17
        assert arrangements_hold(tree) < tree.n / 2
        weights = rng.uniform(0.5, 5.0, m)
        for _ in range(20):
            arm, objects = rng.uniform(0, 1, 2), rng.uniform(0, 1, (m, 3))
            expected = _brute_force(tree, arm, objects, 0.3, weights)
            assert tree.nearest(arm, objects, 0.3, weights) == expected
        assert tree.nearest(tree.arm[17], tree.objects[17], 0.3, weights) == 17


def test_nearest_breaks_ties_across_arrangements_to_the_first_node():
    """Nearest scans the arrangement of least objects' term first and skips those whose term
    exceeds the best distance so far; a node of a later arrangement can still tie it. On a
    grid (arm weight and object weights 1, coordinates 0, 1 or 2) distances such as 1 + 1
    and 2 + 0 tie exactly: the answer is still the first of the nodes at the least distance,
    as the metric written out node by node says, also where that node's arrangement is not
    the one of least term."""
    rng = np.random.default_rng(2)
    grid = np.array([0.0, 1.0, 2.0])
    tied_elsewhere = 0
    for trial in range(10):
        m = 1 + trial % 2
        tree = Tree(State(np.zeros(7), rng.choice(grid, (m, 3))), rng.choice(grid, 2),
                    capacity=4)
        for _ in range(150):
            parent = int(rng.integers(0, tree.n))
            objects = (tree.objects[parent].copy() if rng.random() < 0.6
                       else rng.choice(grid, (m, 3)))
            tree.add(State(np.zeros(7), objects), rng.choice(grid, 2), parent, ())
        arrangements_hold(tree)
        weights = np.ones(m)
        for _ in range(30):
            arm, objects = rng.choice(grid, 2), rng.choice(grid, (m, 3))
            totals = [_written_out(tree.arm[i], tree.objects[i], arm, objects, 1.0, weights)
                      for i in range(tree.n)]
            expected = _brute_force(tree, arm, objects, 1.0, weights)
            assert tree.nearest(arm, objects, 1.0, weights) == expected
            terms = [_written_out(arm, tree.objects[i], arm, objects, 1.0, weights)
                     for i in range(tree.n)]
            tied = [i for i in range(tree.n) if totals[i] == totals[expected]]
            if len(tied) > 1 and terms[expected] > min(terms[i] for i in tied):
                tied_elsewhere += 1
    assert tied_elsewhere > 10, tied_elsewhere


def test_nearest_of_the_first_n_nodes_leaves_the_later_ones_out():
    """The compiled iterations ask Nearest of the nodes added so far (`n`): nodes listed in an
    arrangement at or past n are not answered, even the nearest of all."""
    rng = np.random.default_rng(3)
    tree = Tree(State(np.zeros(7), rng.uniform(0, 1, (2, 3))), rng.uniform(0, 1, 2))
    for _ in range(200):
        parent = int(rng.integers(0, tree.n))
        objects = (tree.objects[parent].copy() if rng.random() < 0.7
                   else rng.uniform(0, 1, (2, 3)))
        tree.add(State(np.zeros(7), objects), rng.uniform(0, 1, 2), parent, ())
    weights = np.array([5.0, 1.0])
    first = Tree.__new__(Tree)
    first.n, first.arm, first.objects = 120, tree.arm[:120], tree.objects[:120]
    left_out = 0
    for _ in range(50):
        arm, objects = rng.uniform(0, 1, 2), rng.uniform(0, 1, (2, 3))
        answer = int(nearest_kernel(tree.arm, 120, tree.nearest_arrays, arm, objects, 0.5,
                                    weights))
        assert answer == _brute_force(first, arm, objects, 0.5, weights)
        left_out += _brute_force(tree, arm, objects, 0.5, weights) >= 120
    assert left_out > 5, left_out




def test_the_metric_alone_is_the_one_nearest_uses():
    """`weighted_distance` (PC-RRT's Dist between a propagation's end and the sample) is the
    metric written out, to rounding, and ranks the tree's nodes as Nearest does."""
    rng = np.random.default_rng(1)
    m = 3
    tree = Tree(State(rng.uniform(-1, 1, 7), rng.uniform(0, 1, (m, 3))), rng.uniform(0, 1, 2))
    for _ in range(200):
        tree.add(State(rng.uniform(-1, 1, 7), rng.uniform(0, 1, (m, 3))), rng.uniform(0, 1, 2),
                 0, ())
    weights = rng.uniform(0.5, 5.0, m)
    arm, objects = rng.uniform(0, 1, 2), rng.uniform(0, 1, (m, 3))
    distances = [weighted_distance(tree.arm[i], tree.objects[i], arm, objects, 0.3, weights)
                 for i in range(tree.n)]
    for i in range(tree.n):
        written = _written_out(tree.arm[i], tree.objects[i], arm, objects, 0.3, weights)
        assert math.isclose(distances[i], written, rel_tol=1e-12)
    assert int(np.argmin(distances)) == tree.nearest(arm, objects, 0.3, weights)


def test_a_search_s_nodes_share_the_arrangements_their_objects_do(monkeypatch):
    """PC-RRT's compiled iterations give each node it adds its arrangement, in arrays that
    start at two nodes and grow (`Tree.make_room`): every node's arrangement holds its
    objects, and the edges that move no object leave far fewer arrangements than nodes."""
    from rearrangement_planner.physics.validation import load_scene
    from rearrangement_planner.planning import PCRRT, PCRRTOptions
    from rearrangement_planner.planning.planners import pcrrt

    trees: list[Tree] = []

    def recorded(root: State, root_arm: np.ndarray) -> Tree:
        trees.append(Tree(root, root_arm, capacity=2))
        return trees[-1]

    monkeypatch.setattr(pcrrt, "Tree", recorded)
    scene = load_scene("default")
    PCRRT(scene, PCRRTOptions(time_limit=60.0, max_iterations=400)).plan(seed=0)
    tree = trees[-1]
    assert tree.n > 100 and len(scene.objects) > 1
    assert arrangements_hold(tree) < tree.n / 2
