"""Settings written once (`model/settings.py`): a NAME=VALUE text that is wrong is named in the
error, quoted at most a line long however long it was."""

from __future__ import annotations

import pytest

from rearrangement_planner.model.settings import SettingSpec, parse_assignments

SPECS = (SettingSpec("trees", 2, "raced trees", 1, 64),)


@pytest.mark.parametrize("item", ["x" * 100_000, "trees=" + "9" * 100_000 + "z"])
def test_a_huge_wrong_setting_is_quoted_short(item):
    with pytest.raises(ValueError) as error:
        parse_assignments(SPECS, [item])
    message = str(error.value)
    assert len(message) < 400 and "more characters)" in message
    assert message.startswith(item[:20])


def test_a_setting_is_parsed_by_its_type():
    assert parse_assignments(SPECS, ["trees = 3"]) == {"trees": 3}
    with pytest.raises(ValueError, match="trees=two: trees takes a int, got 'two'"):
        parse_assignments(SPECS, ["trees=two"])
