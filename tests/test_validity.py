"""Coupled checks: the OMPL checker, the motion validator, and the bound behind it."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from ompl import util as ompl_util
from recheck import recheck_plan

import openup_ompl as oo
from openup_ompl import state_check, validity
from openup_ompl._resources import data_dir
from openup_ompl.benchmark import default_problems_dir
from openup_ompl.collision import CollisionWorld
from openup_ompl.motion_bound import (
    body_bounds,
    body_curvature,
    hand_rate,
    local_reach,
    self_pair_factors,
)
from openup_ompl.validity import ARM_TIGHTEN_FLOOR, COARSE_LEVELS, CoupledChecker

ompl_util.setLogLevel(ompl_util.LOG_ERROR)


@pytest.fixture(scope="module")
def setup() -> oo.GraspPlanningSetup:
    return oo.GraspPlanningSetup(oo.load_scene(oo.default_scene_path()))


def _valid_arms(setup: oo.GraspPlanningSetup, count: int, seed: int) -> list[np.ndarray]:
    robot = setup.problem.robot
    rng = np.random.default_rng(seed)
    arms: list[np.ndarray] = []
    while len(arms) < count:
        arm = rng.uniform(robot.arm_lower, robot.arm_upper)
        if setup.checker.is_valid(arm):
            arms.append(arm)
    return arms


def test_ompl_checker_equals_law_and_collision(setup: oo.GraspPlanningSetup) -> None:
    """si.isValid equals a collision check of the full q whose hand is the law's."""
    si = setup.space_information
    robot = setup.problem.robot
    world = setup.checker.finest_world
    rng = np.random.default_rng(0)
    state = si.allocState()
    verdicts = []
    for _ in range(300):
        arm = rng.uniform(robot.arm_lower, robot.arm_upper)
        state[0:7] = arm.tolist()
        q = robot.full_q(arm, setup.law(setup.checker.normalized_distance(arm)))
        verdicts.append(si.isValid(state))
        assert verdicts[-1] == (not world.in_collision(q))
    assert 0 < sum(verdicts) < len(verdicts)


@pytest.fixture(scope="module", params=sorted(oo.available_robots()))
def robot_setup(request: pytest.FixtureRequest) -> oo.GraspPlanningSetup:
    """The first shipped scene of each robot."""
    return oo.GraspPlanningSetup(
        oo.load_scene(sorted(data_dir("scenes").glob(f"{request.param}_*.toml"))[0])
    )


def test_motion_bound_covers_every_geometry(robot_setup: oo.GraspPlanningSetup) -> None:
    """No collision geometry's reference point moves farther than the displacement bound,
    on random motions and on motions near the grasp, where the fingers follow the law."""
    checker = robot_setup.checker
    robot = robot_setup.problem.robot
    model, geometry = robot.model, robot.collision_model
    data, geometry_data = model.createData(), geometry.createData()

    def placements(arm: np.ndarray) -> np.ndarray:
        pin.updateGeometryPlacements(model, data, geometry, geometry_data, checker.coupled_q(arm))
        return np.array([p.translation.copy() for p in geometry_data.oMg])

    rng = np.random.default_rng(1)
    grasp = robot_setup.goal.solutions[0]
    hand_moved = plateau = 0
    for k in range(300):
        centre = rng.uniform(robot.arm_lower, robot.arm_upper) if k % 2 else grasp
        a = np.clip(centre + rng.normal(0.0, 0.05, centre.size), robot.arm_lower, robot.arm_upper)
        b = np.clip(a + rng.normal(0.0, 0.1, a.size), robot.arm_lower, robot.arm_upper)
        hand_a, hand_b = (checker.coupled_q(x)[robot.hand_idx] for x in (a, b))
        hand_moved += not np.allclose(hand_a, hand_b)
        moved = np.max(np.linalg.norm(placements(b) - placements(a), axis=1))
        assert moved <= float(np.abs(b - a) @ checker.motion_weights) + 1e-12
        # Motions given the bound without the fingers' term keep the hand still.
        if checker.weights(a, b) is checker.plateau_weights:
            plateau += 1
            for t in np.linspace(0.0, 1.0, 11):
                assert np.array_equal(checker.coupled_q(a + t * (b - a))[robot.hand_idx], hand_a)
    assert hand_moved >= 50 and plateau >= 50


def test_motion_spread_bounds_d_along_motions(robot_setup: oo.GraspPlanningSetup) -> None:
    """The per-motion bound of how fast ``d`` changes (from the palm's and the joints'
    placements at the motion's ends) holds between any two states of the motion, is never
    above the global Lipschitz bound, and is far below it on short motions at the grasp
    (the retreat's)."""
    checker = robot_setup.checker
    robot = robot_setup.problem.robot
    grasp = robot_setup.goal.solutions[0]
    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 1.0, 41)
    short = []  # spread / Lipschitz bound on retreat-sized motions at the grasp
    for k in range(80):
        centre = rng.uniform(robot.arm_lower, robot.arm_upper) if k % 4 == 3 else grasp
        a = np.clip(centre + rng.normal(0.0, 0.02, centre.size), robot.arm_lower, robot.arm_upper)
        scale = (0.01, 0.05, 0.2, 0.4)[k % 4]
        b = np.clip(a + rng.normal(0.0, scale, a.size), robot.arm_lower, robot.arm_upper)
        abs_delta = np.abs(b - a)
        spread = checker._motion_spread(a, b, abs_delta)
        lipschitz = float(checker.distance_rates @ abs_delta)
        assert spread <= lipschitz + 1e-12
        if k % 4 == 0:
            short.append(spread / lipschitz)
        d = np.array([checker.normalized_distance(a + x * (b - a)) for x in t])
        gaps = np.abs(d[:, None] - d[None, :])
        assert np.all(gaps <= spread * np.abs(t[:, None] - t[None, :]) + 1e-12)
    assert np.median(short) < 0.6


def _box_corners(geometry: pin.GeometryObject) -> np.ndarray:
    """The 8 corners of a geometry's local bounding box, in its own frame: ``(8, 3)``."""
    shape = geometry.geometry
    shape.computeLocalAABB()
    low, high = np.asarray(shape.aabb_local.min_), np.asarray(shape.aabb_local.max_)
    return np.array(
        [[(high if bit else low)[i] for i, bit in enumerate(bits)] for bits in np.ndindex(2, 2, 2)]
    )


def _sweep_corners(
    robot: oo.Robot,
    geometry_model: pin.GeometryModel,
    corners: dict[int, np.ndarray],
    q: np.ndarray,
    b: np.ndarray,
    t: np.ndarray,
) -> tuple[list[np.ndarray], dict[int, np.ndarray]]:
    """The straight arm motion from ``q``'s arm to ``b`` (the rest of ``q`` still), at the
    parameters ``t`` (from 0 to 1): the arm joints' placements ``(n, 4, 4)`` at both ends,
    and each geometry's box corners in the world at every ``t``, ``(len(t), 8, 3)``."""
    model, data = robot.model, robot.model.createData()
    geometry_data = geometry_model.createData()
    arm_ids = [model.getJointId(n) for n in robot.spec.arm_joints]
    q = q.copy()
    a = q[robot.arm_idx].copy()
    frames: list[np.ndarray] = []
    points: dict[int, list[np.ndarray]] = {g: [] for g in corners}
    for x in t:
        q[robot.arm_idx] = a + x * (b - a)
        pin.forwardKinematics(model, data, q)
        pin.updateGeometryPlacements(model, data, geometry_model, geometry_data)
        if x in (0.0, 1.0):
            frames.append(np.array([data.oMi[j].homogeneous for j in arm_ids]))
        for g, box in corners.items():
            placement = geometry_data.oMg[g]
            points[g].append(box @ placement.rotation.T + placement.translation)
    return frames, {g: np.array(p) for g, p in points.items()}


def test_local_reach_bounds_every_point(robot_setup: oo.GraspPlanningSetup) -> None:
    """The per-motion bound of the arm's share of the displacement, from the placements at
    the motion's two ends, holds for every corner of every moving geometry's box between
    any two states of the motion, whatever the (still) fingers' configuration; it is far
    below the global weights' bound on short motions at the grasp (the retreat's)."""
    checker = robot_setup.checker
    robot = robot_setup.problem.robot
    geometry_model = robot.collision_model
    bodies = body_bounds(robot)
    assert bodies is not None
    corners = {
        i: _box_corners(g)
        for i, g in enumerate(geometry_model.geometryObjects)
        if g.parentJoint != 0
    }
    grasp = robot_setup.goal.solutions[0]
    rng = np.random.default_rng(5)
    t = np.linspace(0.0, 1.0, 41)
    short = []
    for k in range(40):
        centre = rng.uniform(robot.arm_lower, robot.arm_upper) if k % 4 == 3 else grasp
        a = np.clip(centre + rng.normal(0.0, 0.02, centre.size), robot.arm_lower, robot.arm_upper)
        b = np.clip(
            a + rng.normal(0.0, (0.01, 0.05, 0.2, 0.4)[k % 4], a.size),
            robot.arm_lower,
            robot.arm_upper,
        )
        q = robot.full_q(a, rng.uniform(robot_setup.law.lower, robot_setup.law.upper))
        frames, points = _sweep_corners(robot, geometry_model, corners, q, b, t)
        abs_delta = np.abs(b - a)
        bound = local_reach(bodies, frames[0], frames[1], body_curvature(bodies, abs_delta))
        points_t = np.concatenate(list(points.values()), axis=1)  # (len(t), points, 3)
        for i in range(0, t.size, 5):
            moved = np.linalg.norm(points_t - points_t[i], axis=2).max(axis=1)
            assert np.all(moved <= bound * np.abs(t - t[i]) + 1e-9)
        if k % 4 == 0:
            short.append(bound / float(abs_delta @ checker.plateau_weights))
    assert np.median(short) < 0.7


def test_self_pair_margins_cover_the_relative_motion(robot_setup: oo.GraspPlanningSetup) -> None:
    """For every self-collision pair with a margin, the distance between any corner of one
    geometry's box and any corner of the other's changes along a motion no faster than the
    pair's factor times the arm's bound the motion check spaces its states by (the local
    bound, never below half the global one): a state clear by the pair's margin keeps the
    pair apart over the interval it covers. Pairs inside the hand have no margin."""
    checker = robot_setup.checker
    robot = robot_setup.problem.robot
    model = robot.model
    geometry_model = checker.world.geometry_model
    factors = self_pair_factors(robot, geometry_model)
    n_robot = robot.collision_model.ngeoms
    pairs = [k for k, f in enumerate(factors) if f > 0]
    assert pairs and all(f <= 2.0 for f in factors)
    arm_joints = {model.getJointId(n) for n in robot.spec.arm_joints}
    for k, pair in enumerate(geometry_model.collisionPairs):
        if pair.second < n_robot and factors[k] == 0:
            # No margin only inside the hand: no arm joint between the two geometries.
            chains = [
                set(model.supports[geometry_model.geometryObjects[g].parentJoint])
                for g in (pair.first, pair.second)
            ]
            assert not (chains[0] ^ chains[1]) & arm_joints
    corners = {
        g: _box_corners(geometry_model.geometryObjects[g])
        for k in pairs
        for g in (geometry_model.collisionPairs[k].first, geometry_model.collisionPairs[k].second)
    }
    bodies = body_bounds(robot)
    assert bodies is not None
    grasp = robot_setup.goal.solutions[0]
    rng = np.random.default_rng(17)
    t = np.linspace(0.0, 1.0, 21)
    worst = 0.0
    for k in range(24):
        centre = rng.uniform(robot.arm_lower, robot.arm_upper) if k % 2 else grasp
        a = np.clip(centre + rng.normal(0.0, 0.05, centre.size), robot.arm_lower, robot.arm_upper)
        b = np.clip(
            a + rng.normal(0.0, (0.05, 0.2, 0.6)[k % 3], a.size), robot.arm_lower, robot.arm_upper
        )
        q = robot.full_q(a, rng.uniform(robot_setup.law.lower, robot_setup.law.upper))
        frames, points = _sweep_corners(robot, geometry_model, corners, q, b, t)
        abs_delta = np.abs(b - a)
        arm = float(abs_delta @ checker.plateau_weights)
        local = local_reach(bodies, frames[0], frames[1], body_curvature(bodies, abs_delta))
        spacing = min(arm, max(local, ARM_TIGHTEN_FLOOR * arm))
        for p in pairs:
            pair = geometry_model.collisionPairs[p]
            first, second = points[pair.first], points[pair.second]  # (len(t), 8, 3)
            gaps = np.linalg.norm(first[:, :, None] - second[:, None], axis=3)  # (len(t), 8, 8)
            change = np.abs(gaps[:, None] - gaps[None, :]).max(axis=(2, 3))
            allowed = factors[p] * spacing * np.abs(t[:, None] - t[None, :])
            worst = max(worst, float((change / np.maximum(allowed, 1e-15))[allowed > 0].max()))
            assert np.all(change <= allowed + 1e-9)
    assert worst > 0.05  # the bound is not vacuous


def test_batched_hands_are_the_laws(robot_setup: oo.GraspPlanningSetup) -> None:
    """The batches of a motion check and of plan rows, whose states skip forward
    kinematics where the Lipschitz bound of ``d`` keeps them on the plateau, hold at every
    state the hand the law gives from that state's own ``d``, on motions that cross
    ``mga`` as well as far from and close to the grasp."""
    checker = robot_setup.checker
    robot = robot_setup.problem.robot
    grasp = robot_setup.goal.solutions[0]
    rng = np.random.default_rng(7)
    below = crossed = 0
    for k in range(60):
        # At the grasp, leaving it (crossing mga), and anywhere.
        centre = rng.uniform(robot.arm_lower, robot.arm_upper) if k % 3 == 2 else grasp
        a = np.clip(centre + rng.normal(0.0, 0.01, grasp.size), robot.arm_lower, robot.arm_upper)
        b = a + rng.normal(0.0, 0.02 if k % 3 == 0 else 0.4, a.size)
        b = np.clip(b, robot.arm_lower, robot.arm_upper)
        ends = (checker.normalized_distance(a), checker.normalized_distance(b))
        t = np.arange(checker.segment_count(a, b) + 1) / checker.segment_count(a, b)
        arms = a + t[:, None] * (b - a)
        qs, _ = checker._states(a, b - a, t, ends, float(checker.distance_rates @ np.abs(b - a)))
        path = np.concatenate([arms, [a], arms[::3]])
        for batch, states in ((qs, arms), (checker.coupled_qs(path), path)):
            expected = np.array([checker.coupled_q(x) for x in states]).T
            np.testing.assert_allclose(batch, expected, rtol=0.0, atol=1e-12)
        d = np.array([checker.normalized_distance(x) for x in arms])
        below += bool(np.all(d <= robot_setup.law.mga))
        crossed += bool(np.any(d <= robot_setup.law.mga) and np.any(d > robot_setup.law.mga))
    assert below >= 3 and crossed >= 3


def test_fingers_still_where_the_lower_bounds_of_d_say(
    robot_setup: oo.GraspPlanningSetup,
) -> None:
    """The lower bounds of ``d`` a motion check sets its hands from are below the true
    ``d`` (equal to it where ``d <= mga``), and over every interval that
    :meth:`check_motion` counts without the fingers' share (the bounds at its two states
    keep ``d`` above ``mga``) the law's hand stays the plateau's."""
    checker = robot_setup.checker
    robot = robot_setup.problem.robot
    law = robot_setup.law
    grasp = robot_setup.goal.solutions[0]
    rng = np.random.default_rng(13)
    still = 0
    for k in range(30):
        a = np.clip(grasp + rng.normal(0.0, 0.01, grasp.size), robot.arm_lower, robot.arm_upper)
        b = np.clip(
            a + rng.normal(0.0, (0.1, 0.4, 0.8)[k % 3], a.size), robot.arm_lower, robot.arm_upper
        )
        ends = (checker.normalized_distance(a), checker.normalized_distance(b))
        spread = checker._motion_spread(a, b, np.abs(b - a))
        t = np.sort(np.concatenate([[0.0, 1.0], rng.uniform(0.0, 1.0, 30)]))
        _, low = checker._states(a, b - a, t, ends, spread)
        assert low is not None
        d = np.array([checker.normalized_distance(a + x * (b - a)) for x in t])
        assert np.all(low <= d + 1e-12)
        np.testing.assert_allclose(low[d <= law.mga], d[d <= law.mga], rtol=0, atol=1e-12)
        for i in np.flatnonzero(low[:-1] + low[1:] - spread * np.diff(t) > 2.0 * law.mga):
            inside = np.linspace(t[i], t[i + 1], 12)
            assert all(checker.normalized_distance(a + x * (b - a)) > law.mga for x in inside)
            still += 1
    assert still >= 20


def test_hand_rate_bounds_finger_motion(robot_setup: oo.GraspPlanningSetup) -> None:
    """With the arm still, no extreme point of a geometry moves farther than
    ``hand_rate * |d1 - d2|`` when the law moves the fingers from ``d1`` to ``d2``."""
    robot, law = robot_setup.problem.robot, robot_setup.law
    model, geometry = robot.model, robot.collision_model
    data, geometry_data = model.createData(), geometry.createData()
    rate = hand_rate(robot, [model.getJointId(n) for n in robot.hand_joints], law)
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
    corners = []
    for g in geometry.geometryObjects:
        g.geometry.computeLocalAABB()
        # Box corners, pulled in to Coal's bounding sphere (for a sphere: its surface).
        half = 0.5 * (g.geometry.aabb_local.max_ - g.geometry.aabb_local.min_)
        half *= min(1.0, g.geometry.aabb_radius / float(np.linalg.norm(half)))
        corners.append(g.geometry.aabb_local.center() + signs * half)

    def points(d: float) -> np.ndarray:
        q = robot.full_q(robot_setup.goal.solutions[0], law(d))
        pin.updateGeometryPlacements(model, data, geometry, geometry_data, q)
        return np.concatenate(
            [
                c @ p.rotation.T + p.translation
                for p, c in zip(geometry_data.oMg, corners, strict=True)
            ]
        )

    rng = np.random.default_rng(4)
    for d1, d2 in rng.uniform(0.0, law.mga, (100, 2)):
        moved = np.max(np.linalg.norm(points(d2) - points(d1), axis=1))
        assert moved <= rate * abs(d2 - d1) + 1e-12
    assert rate > 0.0


def test_free_states_are_remembered_colliding_ones_are_not(
    setup: oo.GraspPlanningSetup, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A state found free is not checked again (an equal array, by ``is_valid`` or as a
    motion's end) and keeps its ``d``; a colliding state, or one given as a list, is
    checked every time; the memory stays within its bound and ``forget`` empties it."""
    monkeypatch.setattr(state_check, "KNOWN_VALID_MAX", 5)
    checker = CoupledChecker(setup.problem, setup.law)
    robot = setup.problem.robot
    rng = np.random.default_rng(4)
    found: dict[bool, np.ndarray] = {}
    while len(found) < 2:
        arm = rng.uniform(robot.arm_lower, robot.arm_upper)
        found.setdefault(checker.is_valid(arm), arm)
    free, colliding = found[True], found[False]
    checker.is_valid(free)  # the memory may have been restarted since it was found
    before = checker.states_checked
    assert checker._check_state(free.copy()) == (True, checker.normalized_distance(free))
    assert checker.states_checked == before
    assert not checker.is_valid(colliding)
    assert checker.is_valid(free.tolist())
    assert checker.states_checked == before + 2
    checker.forget()
    assert checker.is_valid(free)
    assert checker.states_checked == before + 3
    for _ in range(20):
        checker.is_valid(rng.uniform(robot.arm_lower, robot.arm_upper))
        assert len(checker._known_valid) <= 5


@pytest.mark.parametrize("robot_name", sorted(oo.available_robots()))
def test_long_motions_are_probed_with_the_same_verdicts(
    robot_name: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Long motions (first rounds of ``PROBE_MIN_STATES`` states and more) get the same
    verdicts with the probe as without it, and the refused ones cost fewer states."""
    problem = oo.load_scene(default_problems_dir(robot_name) / "shelf_small.toml")
    probed = CoupledChecker(problem)
    plain = CoupledChecker(problem)
    probe_min = validity.PROBE_MIN_STATES
    rng = np.random.default_rng(8)
    robot = problem.robot
    states = {True: [0, 0], False: [0, 0]}  # verdict -> state checks, probed and plain
    long_motions = 0
    while long_motions < 30:
        a, b = (rng.uniform(robot.arm_lower, robot.arm_upper) for _ in range(2))
        reach = float(np.abs(b - a) @ probed.plateau_weights)
        if reach < probe_min * probed.coarse_resolution:
            continue
        if not (probed.is_valid(a) and probed.is_valid(b)):
            continue
        long_motions += 1
        verdicts = []
        for checker, minimum in ((probed, probe_min), (plain, 10**9)):
            monkeypatch.setattr(validity, "PROBE_MIN_STATES", minimum)
            checker.forget()
            before = checker.states_checked
            verdicts.append(checker.check_motion(a, b))
            states[verdicts[0]][checker is plain] += checker.states_checked - before
        assert verdicts[0] == verdicts[1]
    assert states[False][1] > 0, "no long motion collides"
    assert states[False][0] < 0.5 * states[False][1]


def test_batched_and_serial_motion_checks_agree(setup: oo.GraspPlanningSetup) -> None:
    """The motion check on a parallel world and on a one-thread world (its batches then
    loop over the states) give the same verdicts and counts on valid and colliding motions."""
    problem = setup.problem
    one = CoupledChecker(
        problem,
        setup.law,
        world=CollisionWorld(problem, num_threads=1, padding=setup.checker.world.padding),
    )
    arms = _valid_arms(setup, 60, seed=2)
    verdicts = []
    for a, b in zip(arms[::2], arms[1::2], strict=True):
        b = a + (b - a) * 0.4
        if not setup.checker.is_valid(b):
            continue
        assert one.is_valid(b)  # both remember b: neither checks it again below
        before = (setup.checker.states_checked, one.states_checked)
        verdicts.append(setup.checker.check_motion(a, b))
        assert verdicts[-1] == one.check_motion(a, b)
        counts = (setup.checker.states_checked - before[0], one.states_checked - before[1])
        assert counts[0] == counts[1]
    assert True in verdicts and False in verdicts


def test_coarse_pass_gives_the_fine_verdicts_with_fewer_states(
    setup: oo.GraspPlanningSetup,
) -> None:
    """The coarse pass (wider padding, sparser states) accepts and refuses the same
    motions as checking at the resolution directly, and checks fewer states for the free
    motions far from the obstacles."""
    problem, law = setup.problem, setup.law
    fine = CoupledChecker(problem, law, coarse_levels=0)
    coarse = setup.checker
    assert coarse.coarse_resolution == 2**COARSE_LEVELS * fine.coarse_resolution
    arms = _valid_arms(setup, 80, seed=5)
    verdicts, fewer = [], 0
    for a, b in zip(arms[::2], arms[1::2], strict=True):
        b = a + (b - a) * 0.4
        counts = []
        for checker in (fine, coarse):
            before = checker.states_checked
            verdict = checker.check_motion(a, b)
            counts.append(checker.states_checked - before)
        verdicts.append(verdict)
        assert fine.check_motion(a, b) == verdict
        fewer += verdict and counts[1] < counts[0] / 2
    assert True in verdicts and False in verdicts
    assert fewer >= 3


def test_accepted_motions_are_free_at_any_resolution(setup: oo.GraspPlanningSetup) -> None:
    """A motion the validator accepts is collision-free, unpadded, at 20x its resolution."""
    problem = setup.problem
    exact = CollisionWorld(problem, num_threads=1)
    checker = setup.checker
    arms = _valid_arms(setup, 40, seed=3)
    accepted = 0
    for a, b in zip(arms[::2], arms[1::2], strict=True):
        b = a + (b - a) * 0.3
        if not (checker.is_valid(b) and checker.check_motion(a, b)):
            continue
        accepted += 1
        steps = 20 * checker.segment_count(a, b)
        for t in np.linspace(0.0, 1.0, steps + 1):
            assert not exact.in_collision(checker.coupled_q(a + t * (b - a)))
    assert accepted >= 5


def test_accepted_motions_near_the_grasp_are_free(robot_setup: oo.GraspPlanningSetup) -> None:
    """Near the grasp, where the fingers close around the object, thin margins cut the
    motions finest and the law moves the fingers over part of each motion only: a motion
    the checker accepts is collision-free, unpadded, with the law's hand, at ten times the
    resolution of the global bound (fingers included) everywhere along it."""
    checker = robot_setup.checker
    robot = robot_setup.problem.robot
    exact = CollisionWorld(robot_setup.problem, num_threads=1)
    # The palm's straight retreat from the grasp, 25 mm a step, out past mga.
    retreat = [robot_setup.goal.solutions[0]]
    step = -0.025 * robot.spec.approach
    while len(retreat) < 12:
        nxt = robot_setup.goal.ik.palm_step(retreat[-1], step)
        if nxt is None:
            break
        retreat.append(nxt)
    assert len(retreat) >= 6
    rng = np.random.default_rng(11)
    accepted = crossing = 0
    for _ in range(24):
        i, j = sorted(rng.choice(len(retreat), 2, replace=False))
        a = retreat[i]
        b = np.clip(retreat[j] + rng.normal(0.0, 0.02, a.size), robot.arm_lower, robot.arm_upper)
        if not checker.check_motion(a, b):
            continue
        accepted += 1
        steps = 10 * checker.segment_count(a, b)
        d = []
        for t in np.linspace(0.0, 1.0, steps + 1):
            arm = a + t * (b - a)
            assert not exact.in_collision(checker.coupled_q(arm))
            d.append(checker.normalized_distance(arm))
        crossing += min(d) <= robot_setup.law.mga < max(d)
    assert accepted >= 6 and crossing >= 2


def test_grasp_tighter_than_the_padding_is_planned(tmp_path: Path) -> None:
    """Fingers 1.5 mm from the can, less than the 3 mm padding, still plan exactly."""
    text = oo.default_scene_path().read_text()
    old = "c = [0.035, 0.035]"
    assert old in text
    scene = tmp_path / "tight.toml"
    scene.write_text(text.replace(old, "c = [0.0315, 0.0315]"))
    setup = oo.GraspPlanningSetup(oo.load_scene(scene))
    assert setup.checker.paddings[0] > 0.0015 > setup.checker.paddings[-1]
    plan = setup.solve(planner="ikbirrt", seed=0)
    result = recheck_plan(json.loads(plan.save(tmp_path / "plan.json").read_text()))
    assert result.colliding == []
    assert result.position_error <= 1e-3


def test_pool_and_thread_batches_agree(setup: oo.GraspPlanningSetup) -> None:
    """Batches of PARALLEL_MIN_STATES and more (Pinocchio's pool) and smaller ones (one by
    one in this thread) give each state's own verdict, colliding states included."""
    from openup_ompl.collision import PARALLEL_MIN_STATES

    world = setup.checker.finest_world
    robot = setup.problem.robot
    rng = np.random.default_rng(11)
    arms = rng.uniform(robot.arm_lower, robot.arm_upper, (3 * PARALLEL_MIN_STATES, 7))
    qs = np.asfortranarray(np.stack([setup.checker.coupled_q(a) for a in arms]).T)
    expected = np.array([world.in_collision(qs[:, i]) for i in range(qs.shape[1])])
    assert 0 < expected.sum() < expected.size
    for size in (1, PARALLEL_MIN_STATES - 1, PARALLEL_MIN_STATES, qs.shape[1]):
        flags = world.batch_in_collision(qs[:, :size], stop_at_first=False)
        assert flags.tolist() == expected[:size].tolist()
        assert bool(np.any(world.batch_in_collision(qs[:, :size]))) == bool(expected[:size].any())


def test_no_collision_query_warm_starts_gjk(setup: oo.GraspPlanningSetup) -> None:
    """Every collision request of a world's thread context and of its pool has GJK's cached
    guess off (an answer must not depend on the queries before it), and so has every
    distance request of the grasp closer, which computes distances."""
    import warnings

    import coal

    world = setup.checker.finest_world
    qs = np.asfortranarray(
        np.repeat(setup.checker.coupled_q(np.asarray(setup.problem.start))[:, None], 40, axis=1)
    )
    world.batch_in_collision(qs)  # builds the pool
    datas = [world.context().geometry_data, *world._pool.getGeometryDatas()]
    closer = oo.HandCloser(setup.problem)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        for geometry_data in datas:
            for request in geometry_data.collisionRequests:
                assert not request.enable_cached_gjk_guess
                assert request.gjk_initial_guess == coal.GJKInitialGuess.DefaultGuess
        for request in closer._geometry_data.distanceRequests:
            assert not request.enable_cached_gjk_guess
