"""The coupled state check, in either of its orders (the plateau hand's query first, or
forward kinematics for ``d`` first), gives the verdict and ``d`` of a fresh reference."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import openup_ompl as oo
from openup_ompl._resources import data_dir
from openup_ompl.collision import live_translation
from openup_ompl.validity import CoupledChecker

ROBOTS = ("panda", "lwa3_sdh", "ur5_allegro")


def _states(setup: oo.GraspPlanningSetup, count: int, seed: int) -> list[np.ndarray]:
    """Runs of uniform states and of states around an IK solution of the grasp, alternating
    so that both orders run, and the plateau-first query meets states under ``mga``."""
    robot = setup.problem.robot
    rng = np.random.default_rng(seed)
    grasp = setup.goal.ensure_solution()
    states: list[np.ndarray] = []
    for run in range(count // 5):
        for _ in range(5):
            if run % 2:
                step = rng.normal(scale=0.05 * (run % 4), size=grasp.size)
                states.append(np.clip(grasp + step, robot.arm_lower, robot.arm_upper))
            else:
                states.append(rng.uniform(robot.arm_lower, robot.arm_upper))
    return states


def _reference(checker: CoupledChecker, arm: np.ndarray) -> tuple[bool, float]:
    """Verdict (pair loop on fresh data, the world's margins) and ``d`` (forward kinematics)."""
    d = checker.normalized_distance(arm)
    q = checker.robot.full_q(arm, checker.law(d))
    free = not checker.finest_world.colliding_pairs(q)
    return free, (np.inf if checker.law.fixed is not None else d)


@pytest.fixture(scope="module", params=ROBOTS)
def setup(request: pytest.FixtureRequest) -> oo.GraspPlanningSetup:
    return oo.GraspPlanningSetup(oo.load_scene(data_dir("scenes") / f"{request.param}_can.toml"))


def test_both_orders_match_the_reference(setup: oo.GraspPlanningSetup) -> None:
    """Every state's verdict and d equal the reference's, whichever order checked it."""
    checker = setup.checker
    states = _states(setup, 200, seed=1)
    mga = checker.law.mga
    near = 0
    for arm in states:
        free, d = checker._check_state(arm.tolist())  # a list: never read back from memory
        expected_free, expected_d = _reference(checker, arm)
        assert free == expected_free
        assert d == pytest.approx(expected_d, rel=1e-12, abs=1e-12)
        near += expected_d <= mga
    assert 0 < near < len(states), "the states must lie on both sides of mga"


def test_fixed_hand_and_weighted_distance_match_the_reference(
    setup: oo.GraspPlanningSetup,
) -> None:
    """A fixed hand, and the law on the weighted distance, give the reference's verdicts."""
    problem, law = setup.problem, setup.checker.law
    states = _states(setup, 60, seed=2)
    for changed in (law.with_options(fixed=law.w), law.with_options(distance="weighted")):
        checker = CoupledChecker(problem, changed)
        for arm in states:
            free, d = checker._check_state(arm)
            expected_free, expected_d = _reference(checker, arm)
            assert free == expected_free
            assert d == pytest.approx(expected_d, rel=1e-12, abs=1e-12)


def test_a_remembered_state_is_not_queried_again(setup: oo.GraspPlanningSetup) -> None:
    """A free state given as an array is answered from memory, with its d, uncounted."""
    checker = CoupledChecker(setup.problem, setup.law)
    arm = setup.problem.start.astype(float)
    free, d = checker._check_state(arm)
    assert free
    counted = checker.states_checked
    assert checker._check_state(arm.copy()) == (True, d)
    assert checker.states_checked == counted


def test_live_palm_view_follows_the_frame(setup: oo.GraspPlanningSetup) -> None:
    """The context's palm view reads data.oMf's palm position after every frame update."""
    robot = setup.problem.robot
    model = robot.model
    data = model.createData()
    view = live_translation(model, data, robot.palm_frame_id)
    assert view is not None, "Pinocchio's binding returns a copy: the check falls back to it"
    rng = np.random.default_rng(3)
    for _ in range(5):
        q = robot.full_q(rng.uniform(robot.arm_lower, robot.arm_upper), setup.law(1.0))
        pin.forwardKinematics(model, data, q)
        placement = pin.updateFramePlacement(model, data, robot.palm_frame_id)
        np.testing.assert_array_equal(view, placement.translation)
