"""Bad input to the public API's functions and methods (beyond the option classes, whose
checks their own modules test): each is a ConfigError naming the argument, where it was a
TypeError, ValueError, IndexError, AttributeError, ZeroDivisionError or a silently wrong
result before (an audit of the docstrings against the code, 2026-12-03)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pinocchio as pin
import pytest

import openup_ompl as oo
from openup_ompl.hand_law import HandLaw
from openup_ompl.ik import IKSolver
from openup_ompl.perception import kinect_sigmas
from openup_ompl.robustness import RobustnessOptions, run_robustness


@pytest.fixture(scope="module")
def setup() -> oo.GraspPlanningSetup:
    return oo.GraspPlanningSetup(oo.load_scene(oo.default_scene_path()))


def _root(setup: oo.GraspPlanningSetup) -> np.ndarray:
    return setup.goal.solutions[0]


Setup = oo.GraspPlanningSetup
#: Case -> (a call on the default scene's setup, what its error must name).
CASES: dict[str, tuple[Callable[[Setup], Any], str]] = {
    "hand_law of a string": (lambda s: s.problem.robot.hand_law("x"), "hand: got 'x'"),
    "ragged c": (lambda s: s.problem.robot.hand_law(c=[1, [2]]), "hand.c"),
    "arm of letters": (lambda s: s.problem.robot.check_arm("abc", "arm"), "arm: got 'abc'"),
    "arm None": (lambda s: s.problem.robot.check_arm(None, "arm"), "arm: got None"),
    "scalar hand": (lambda s: s.problem.robot.expand_hand(0.01), "hand configuration"),
    "hand of 3 values": (
        lambda s: s.problem.robot.full_q(s.problem.robot.spec.home, [0.01] * 3),
        "hand: got",
    ),
    "arm of 3 values": (lambda s: s.problem.robot.full_q([0.0] * 3, [0.01]), "arm: got"),
    "unknown law field": (lambda s: s.law.with_options(bogus=1), "hand.bogus"),
    "law table a string": (
        lambda s: HandLaw.from_table("x", s.law.lower, s.law.upper),
        "hand: got 'x'",
    ),
    "IK target a list": (lambda s: IKSolver(s.problem.robot, [0, 0, 0, 0, 0, 0, 1]), "target"),
    "IK options a dict": (
        lambda s: IKSolver(s.problem.robot, pin.SE3.Identity(), {}),
        "options",
    ),
    "no restart": (lambda s: s.goal.sample(0), "max_restarts"),
    "retreat step 0": (lambda s: s.goal.retreat(_root(s), 0.1, 0.0, 0.3), "step"),
    "retreat to infinity": (lambda s: s.goal.retreat(_root(s), np.inf, 0.025, 0.3), "length"),
    "retreat joint step 0": (
        lambda s: s.goal.retreat(_root(s), 0.1, 0.025, 0.0),
        "max_joint_step",
    ),
    "pregrasp of 5 m": (lambda s: oo.PlanningOptions(pregrasp=5.0), "pregrasp"),
    "sweep options a string": (lambda s: run_robustness(options="x"), "options"),
    "sweep scene a number": (lambda s: run_robustness(scene=5), "scene"),
    "sweep torsion a string": (lambda s: RobustnessOptions(torsion="a"), "torsion"),
    "negative padding": (lambda s: s.problem.environment[0].geometry(-0.1), "padding"),
    "negative depth": (lambda s: kinect_sigmas(np.array([-1.0]), np.array([0.0])), "depth"),
    "grazing incidence": (
        lambda s: kinect_sigmas(np.array([1.0]), np.array([np.pi / 2])),
        "incidence",
    ),
}


@pytest.mark.parametrize("case", CASES)
def test_bad_argument_is_a_config_error_naming_it(setup, case):
    call, named = CASES[case]
    with pytest.raises(oo.ConfigError) as error:
        call(setup)
    assert named in str(error.value)
