"""What a search that ends without a plan reports (`machinery.search.Search`)."""

import numpy as np

from rearrangement_planner.model.state import State
from rearrangement_planner.physics.step import Invalid
from rearrangement_planner.planning import Outcome, PCRRTOptions, StopReason
from rearrangement_planner.planning.machinery.propagation import Propagation
from rearrangement_planner.planning.machinery.search import Search
from rearrangement_planner.planning.machinery.tree import Tree


def _search() -> Search:
    search = Search(PCRRTOptions(), seed=0, stop=None, progress=None)
    search.tree = Tree(State(np.zeros(7), np.zeros((2, 3))), np.zeros(2))
    search.goal_index, search.start_distance, search.best = 0, 0.4, 0.1
    return search


def _propagation(stopped, subject: int = -1) -> Propagation:
    return Propagation(np.zeros((2, 7)), np.zeros((2, 2, 3)), 0.1, stopped, frozenset(),
                       subject)


def test_an_unsolved_search_reports_the_goal_objects_progress_and_the_commonest_refusals():
    search = _search()
    for stopped, subject in [(Invalid.TURNING, 0)] * 3 + [(Invalid.TIPPING, 1),
                                                          (StopReason.GOAL, -1), (None, -1)]:
        search.propagated(_propagation(stopped, subject))
    assert search.steps == 12
    message = search.failure(Outcome.PLANNING_FAILED, "no plan within max_iterations 6").message
    assert message == ("no plan within max_iterations 6; the goal object came within 0.10 m "
                       "of its goal point (from 0.40 m); of the 4 propagations the model cut "
                       "short: object_turns of the goal object 75%, object_would_tip 25%")


def test_a_goal_object_that_never_moved_and_a_cancel_say_so():
    search = _search()
    search.best = search.start_distance
    assert search.why_unsolved() == ("; the goal object never came nearer its goal point than "
                                     "its start, 0.40 m away")
    assert search.failure(Outcome.CANCELLED, "cancelled").message == "cancelled"
