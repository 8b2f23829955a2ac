"""Bad input to the public API's functions and methods (beyond the option classes, whose
checks their own modules test): each is a ConfigError naming the argument, where it was a
TypeError, ValueError, IndexError, AttributeError, ZeroDivisionError or a silently wrong
result before (an audit of the docstrings against the code, 2026-12-03). Then inputs a
second audit found accepted or ignored: refused planners given as instances, an IKBiRRT
instance's seed, paths beyond the joint limits, problems and shapes built in code."""

from __future__ import annotations

import contextlib
import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
from ompl import geometric as og

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


#: A pose of a shape built in code (world frame, identity rotation).
POSE = [0.5, 0.0, 0.2, 0.0, 0.0, 0.0, 1.0]


def _with_obstacles(setup: oo.GraspPlanningSetup, obstacles: Any) -> oo.Problem:
    return dataclasses.replace(setup.problem, obstacles=obstacles)


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
    "problem without a law": (
        lambda s: dataclasses.replace(s.problem, hand_law=None),
        "problem.hand_law: got None",
    ),
    "obstacles None": (lambda s: _with_obstacles(s, None), "problem.obstacles: got None"),
    "obstacle a string": (lambda s: _with_obstacles(s, ["x"]), "problem.obstacles[0]: got 'x'"),
    "obstacle named twice": (
        lambda s: _with_obstacles(s, [*s.problem.obstacles, s.problem.obstacles[0]]),
        f"obstacle name: got {'table'!r}",
    ),
    "object a string": (
        lambda s: dataclasses.replace(s.problem, object="can"),
        "problem.object: got 'can'",
    ),
    "negative box": (
        lambda s: oo.Shape("wall", "box", POSE, size=[0.1, -0.3, 0.1]),
        "shape 'wall'.size: got [0.1, -0.3, 0.1]",
    ),
    "box of one size": (lambda s: oo.Shape("wall", "box", POSE, size=-0.3), "shape 'wall'.size"),
    "cone": (lambda s: oo.Shape("c", "cone", POSE, radius=0.1), "shape 'c'.shape: got 'cone'"),
    "sphere without radius": (
        lambda s: oo.Shape("ball", "sphere", POSE),
        "shape 'ball'.radius: got None",
    ),
    "box with a radius": (
        lambda s: oo.Shape("wall", "box", POSE, size=[0.1] * 3, radius=0.1),
        "shape 'wall'.radius",
    ),
    "zero quaternion": (
        lambda s: oo.Shape("ball", "sphere", [0.5, 0, 0.2, 0, 0, 0, 0], radius=0.1),
        "shape 'ball'.pose",
    ),
    "unnamed shape": (lambda s: oo.Shape("", "sphere", POSE, radius=0.1), "shape.name"),
    "weightless object": (
        lambda s: dataclasses.replace(s.problem.object, mass=0.0),
        "shape 'can'.mass: got 0.0",
    ),
    "obstacle with a mass": (
        lambda s: dataclasses.replace(
            s.problem, obstacles=[oo.Shape("block", "box", POSE, size=[0.1] * 3, mass=1.0)]
        ),
        "problem.obstacles[0].mass: got 1.0",
    ),
}


@pytest.mark.parametrize("case", CASES)
def test_bad_argument_is_a_config_error_naming_it(setup, case):
    call, named = CASES[case]
    with pytest.raises(oo.ConfigError) as error:
        call(setup)
    assert named in str(error.value)


@pytest.mark.parametrize("kind", [og.PRM, og.PRMstar, og.AORRTC], ids=lambda k: k.__name__)
def test_planner_refused_by_name_is_refused_as_an_instance(setup, kind):
    """An OMPL planner refused by name is refused, with the reason, when given built:
    PRM and PRMstar hung on the Python goal region and AORRTC crashed."""
    planner = kind(setup.space_information)
    try:
        with pytest.raises(oo.ConfigError) as error:
            setup.solve(time_limit=1.0, planner=planner)
    finally:
        if kind is og.AORRTC:  # OMPL 2.0.1 crashes freeing an AORRTC never set up
            planner.setProblemDefinition(setup.simple_setup.getProblemDefinition())
            planner.setup()
    assert f"planner: got {kind.__name__!r}" in str(error.value)
    assert ("crashes" if kind is og.AORRTC else "deadlocks") in str(error.value)


def test_ikbirrt_instance_keeps_its_own_seed(setup):
    """Without a seed of the call, an IKBiRRT built with a seed plans the same path every
    time and the plan records that seed; a seed of the call still wins."""
    options = oo.IKBiRRTOptions(seed=3)
    plans = [setup.solve(planner=oo.IKBiRRT(setup.space_information, options)) for _ in range(3)]
    assert [plan.seed for plan in plans] == [3, 3, 3]
    assert all(np.array_equal(plan.path, plans[0].path) for plan in plans)
    same = setup.solve(planner=oo.IKBiRRT(setup.space_information), seed=3)
    assert same.seed == 3 and np.array_equal(same.path, plans[0].path)
    assert setup.solve(planner=oo.IKBiRRT(setup.space_information, options), seed=5).seed == 5


@pytest.mark.parametrize(
    ("columns", "value", "joint"),
    [(0, 10.0, "panda_joint1"), (slice(7, None), 0.5, "panda_finger_joint1")],
    ids=["arm", "hand"],
)
def test_verify_refuses_a_row_beyond_the_joint_limits(setup, columns, value, joint):
    """``verify`` names the row, the joint and the value of a path that leaves its joint
    limits, arm or hand, even where the row is collision-free."""
    path = setup.solve(seed=1).path
    setup.verify(path)
    row = len(path) // 2
    bad = path.copy()
    bad[row, columns] = value
    with pytest.raises(oo.VerifyFailed) as error:
        setup.verify(bad)
    assert f"path row {row}: joint {joint} at {value:g}" in str(error.value)


def test_shapes_and_problems_built_in_code_take_lists_arrays_and_tuples(setup):
    """A shape's pose and size given as a list, a tuple or an array make the same shape
    (a unit quaternion normalised, floats stored); a tuple of obstacles becomes a list."""
    size = [0.1, 0.2, 0.3]
    box = [
        oo.Shape("crate", "box", kind(POSE), size=kind(size)) for kind in (list, tuple, np.array)
    ]
    for shape in box:
        assert isinstance(shape.pose, np.ndarray) and isinstance(shape.size, np.ndarray)
        assert np.array_equal(shape.pose, POSE) and np.array_equal(shape.size, size)
    tilted = oo.Shape("ball", "sphere", [0, 0, 0, 0, 0, 0, 1.0005], radius=np.float32(0.25))
    assert tilted.pose[-1] == 1.0 and tilted.radius == 0.25 and type(tilted.radius) is float
    problem = _with_obstacles(setup, (*setup.problem.obstacles, box[0]))
    assert isinstance(problem.obstacles, list) and problem.obstacles[-1] is box[0]


def test_a_goal_region_stops_offering_goals_at_the_time_limit():
    """BITstar draws ``maxSampleCount()`` goals up front without looking at the time, an
    IK solve each: a region of 10,000 (the class's default) ran 73 s of a 5 s limit. solve()
    gives the region its deadline, past which it offers no more; the region set on the
    setup by hand gets it too, and loses it after the run."""
    from ompl import geometric as og

    setup = oo.GraspPlanningSetup(oo.load_scene(oo.default_scene_path()))
    region = oo.IKGoalRegion(setup.space_information, setup.goal, max_samples=10_000)
    setup.simple_setup.setGoal(region)
    # The run's outcome is not the point: how many goals it drew is, run after run (each
    # planner counts its own draws from 0).
    for seed in (1, 2):
        drawn = region.draws
        with contextlib.suppress(oo.PlanningFailed):
            setup.solve(time_limit=0.5, planner=og.BITstar(setup.space_information), seed=seed)
        assert 0 < region.draws - drawn < region.max_samples // 4
        assert region.deadline is None and region.maxSampleCount() == 10_000
