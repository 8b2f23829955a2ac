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


def _cases(setup: oo.GraspPlanningSetup) -> dict[str, tuple[Callable[[], Any], str]]:
    robot, law, goal = setup.problem.robot, setup.law, setup.goal
    root = goal.solutions[0]
    return {
        "hand_law of a string": (lambda: robot.hand_law("x"), "hand: got 'x'"),  # type: ignore[arg-type]
        "ragged c": (lambda: robot.hand_law(c=[1, [2]]), "hand.c"),
        "arm of letters": (lambda: robot.check_arm("abc", "arm"), "arm: got 'abc'"),  # type: ignore[arg-type]
        "arm None": (lambda: robot.check_arm(None, "arm"), "arm: got None"),  # type: ignore[arg-type]
        "scalar hand": (lambda: robot.expand_hand(0.01), "hand configuration"),  # type: ignore[arg-type]
        "hand of 3 values": (lambda: robot.full_q(robot.spec.home, [0.01] * 3), "hand: got"),
        "arm of 3 values": (lambda: robot.full_q([0.0] * 3, [0.01]), "arm: got"),
        "unknown law field": (lambda: law.with_options(bogus=1), "hand.bogus"),
        "law table a string": (
            lambda: HandLaw.from_table("x", law.lower, law.upper),  # type: ignore[arg-type]
            "hand: got 'x'",
        ),
        "IK target a list": (
            lambda: IKSolver(robot, [0, 0, 0, 0, 0, 0, 1]),  # type: ignore[arg-type]
            "target",
        ),
        "IK options a dict": (
            lambda: IKSolver(robot, pin.SE3.Identity(), {}),  # type: ignore[arg-type]
            "options",
        ),
        "no restart": (lambda: goal.sample(0), "max_restarts"),
        "retreat step 0": (lambda: goal.retreat(root, 0.1, 0.0, 0.3), "step"),
        "retreat to infinity": (lambda: goal.retreat(root, np.inf, 0.025, 0.3), "length"),
        "retreat joint step 0": (lambda: goal.retreat(root, 0.1, 0.025, 0.0), "max_joint_step"),
        "pregrasp of 5 m": (lambda: oo.PlanningOptions(pregrasp=5.0), "pregrasp"),
        "sweep options a string": (lambda: run_robustness(options="x"), "options"),  # type: ignore[arg-type]
        "sweep scene a number": (lambda: run_robustness(scene=5), "scene"),  # type: ignore[arg-type]
        "sweep torsion a string": (lambda: RobustnessOptions(torsion="a"), "torsion"),  # type: ignore[arg-type]
        "negative padding": (lambda: setup.problem.environment[0].geometry(-0.1), "padding"),
        "negative depth": (lambda: kinect_sigmas(np.array([-1.0]), np.array([0.0])), "depth"),
        "grazing incidence": (
            lambda: kinect_sigmas(np.array([1.0]), np.array([np.pi / 2])),
            "incidence",
        ),
    }


@pytest.mark.parametrize(
    "case",
    [
        "hand_law of a string",
        "ragged c",
        "arm of letters",
        "arm None",
        "scalar hand",
        "hand of 3 values",
        "arm of 3 values",
        "unknown law field",
        "law table a string",
        "IK target a list",
        "IK options a dict",
        "no restart",
        "retreat step 0",
        "retreat to infinity",
        "retreat joint step 0",
        "pregrasp of 5 m",
        "sweep options a string",
        "sweep scene a number",
        "sweep torsion a string",
        "negative padding",
        "negative depth",
        "grazing incidence",
    ],
)
def test_bad_argument_is_a_config_error_naming_it(setup, case):
    call, named = _cases(setup)[case]
    with pytest.raises(oo.ConfigError) as error:
        call()
    assert named in str(error.value)


def test_every_case_is_run(setup):
    """The parametrised list names every case of the table (none left out by a typo)."""
    ids = test_bad_argument_is_a_config_error_naming_it.pytestmark[0].args[1]
    assert sorted(ids) == sorted(_cases(setup))
