"""The goal region's approach takes what a user's OMPL pipeline holds: an OMPL state as
well as joint values."""

from __future__ import annotations

import numpy as np
import pytest

import openup_ompl as oo
from openup_ompl.exceptions import ConfigError


@pytest.fixture(scope="module")
def default_problem() -> oo.Problem:
    """The default scene (the Panda's can)."""
    return oo.load_scene(oo.default_scene_path())


def test_approach_takes_an_ompl_state_or_joint_values(default_problem: oo.Problem) -> None:
    """``approach`` and ``is_pregrasp`` give the same answer for an OMPL state as for its
    joint values (list or array), and refuse anything else naming it."""
    setup = oo.GraspPlanningSetup(default_problem, pregrasp=0.1)
    region = setup.goal_region
    dof = default_problem.robot.arm_idx.size
    state = setup.space_information.allocState()
    region.sampleGoal(state)
    values = [state[i] for i in range(dof)]
    expected = region.approach(np.array(values))
    assert expected.shape[0] >= 1
    for arm in (state, values, tuple(values)):
        assert region.is_pregrasp(arm)
        np.testing.assert_array_equal(region.approach(arm), expected)
    with pytest.raises(ConfigError, match="arm"):
        region.approach(object())
