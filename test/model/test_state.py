"""The planning state's constructors (model/state.py)."""

import numpy as np
import pytest

from rearrangement_planner.model.state import State


def test_rows_gives_one_read_only_state_per_row_viewing_the_arrays():
    """`State.rows` is `State.trusted` per row, without a copy: each state holds views of the
    rows, and neither they nor the arrays can be written afterwards."""
    rng = np.random.default_rng(3)
    arm, objects = rng.random((4, 7)), rng.random((4, 2, 3))
    states = State.rows(arm, objects)
    assert len(states) == 4
    for k, state in enumerate(states):
        assert isinstance(state, State)
        assert np.array_equal(state.q, arm[k]) and np.array_equal(state.objects, objects[k])
        assert np.shares_memory(state.q, arm) and np.shares_memory(state.objects, objects)
        assert state.equals(State.trusted(arm[k].copy(), objects[k].copy()))
        with pytest.raises(ValueError, match="read-only"):
            state.objects[0, 0] = 1.0
    with pytest.raises(ValueError, match="read-only"):
        arm[0, 0] = 1.0
    assert State.rows(np.empty((0, 7)), np.empty((0, 2, 3))) == []
