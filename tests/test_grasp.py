"""Closing the fingers until contact, and the force-closure and enclosure tests."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.spatial import ConvexHull, QhullError

import openup_ompl as oo
from openup_ompl._resources import data_dir
from openup_ompl.collision import CollisionWorld
from openup_ompl.exceptions import ConfigError, InvalidProblem
from openup_ompl.grasp import (
    ClosingOptions,
    HandCloser,
    close_hand,
    closed_configuration,
    enclosed,
    force_closure,
    object_axis,
)
from openup_ompl.planning import GraspPlanningSetup
from openup_ompl.robustness import displaced

TOLERANCE = 0.5e-3  # [m] the bound on where a finger stops


def _grasp_state(scene: str) -> tuple[oo.Problem, np.ndarray]:
    """A scene and a collision-free full configuration at its grasp pose (hand at c)."""
    problem = oo.load_scene(data_dir("scenes") / scene)
    setup = GraspPlanningSetup(problem)
    arm = setup.goal.solutions[0]
    return problem, setup.checker.coupled_q(arm)


@pytest.fixture(scope="module")
def panda_grasp() -> tuple[oo.Problem, np.ndarray]:
    return _grasp_state("panda_can.toml")


@pytest.fixture(scope="module")
def sdh_grasp() -> tuple[oo.Problem, np.ndarray]:
    return _grasp_state("lwa3_sdh_can.toml")


def _radial_gap(point: np.ndarray, shape: oo.Shape) -> float:
    """Distance of a world point from a cylinder's lateral surface (outside > 0)."""
    local = shape.placement.actInv(point)
    assert shape.radius is not None
    return float(math.hypot(local[0], local[1]) - shape.radius)


@pytest.mark.parametrize("fixture", ["panda_grasp", "sdh_grasp"])
def test_fingers_stop_at_the_cylinder_surface(fixture: str, request: pytest.FixtureRequest) -> None:
    """Every finger that touches the can stops outside it, within 0.5 mm of its true
    (analytic) surface; closing it 1 mm further would penetrate."""
    problem, q = request.getfixturevalue(fixture)
    result = close_hand(problem, q)
    assert problem.object is not None
    assert len(result.contacts) >= 2
    world = CollisionWorld(problem)
    assert not world.in_collision(result.q), world.colliding_pairs(result.q)
    robot = problem.robot
    closed = closed_configuration(problem)
    for contact in result.contacts:
        assert 0.0 < contact.distance <= TOLERANCE
        assert abs(_radial_gap(contact.point, problem.object)) < 1e-5  # on the surface
        finger_point = contact.point - contact.distance * contact.normal
        assert 0.0 < _radial_gap(finger_point, problem.object) <= TOLERANCE + 1e-6
    # Push every joint that stopped short of its closed value on by ~1 mm at the fingertip.
    pushed = result.hand.copy()
    short = np.flatnonzero(np.abs(closed - result.hand) > 1e-9)
    assert short.size > 0
    for i in short:
        joint = robot.model.joints[robot.model.getJointId(robot.spec.hand_joints[i])]
        prismatic = joint.shortname().startswith("JointModelP")
        step = 1e-3 if prismatic else 1e-3 / 0.02  # revolute: ~1 mm at 2 cm from the axis
        pushed[i] += np.sign(closed[i] - result.hand[i]) * step
    assert world.in_collision(robot.full_q(q[robot.arm_idx], pushed))


@pytest.mark.parametrize("kind", ["box", "sphere"])
def test_fingers_stop_on_a_box_and_a_sphere(
    kind: str, sdh_grasp: tuple[oo.Problem, np.ndarray]
) -> None:
    """The SDH closing on a box or a sphere where the can was: every contact point lies on
    the shape's analytic surface, its finger within 0.5 mm of it, and the grasp holds."""
    problem, q = sdh_grasp
    assert problem.object is not None
    pose = problem.object.pose
    if kind == "box":
        shape = oo.Shape("box", "box", pose, size=np.array([0.06, 0.06, 0.16]))
    else:
        shape = oo.Shape("ball", "sphere", pose, radius=0.033)
    result = close_hand(dataclasses.replace(problem, object=shape), q)
    assert len(result.contacts) >= 3
    for contact in result.contacts:
        assert 0.0 < contact.distance <= TOLERANCE
        local = shape.placement.actInv(contact.point)
        if kind == "box":
            assert shape.size is not None
            ratio = np.abs(local) / (shape.size / 2)
            assert ratio.max() == pytest.approx(1.0, abs=1e-4)  # on a face
        else:
            assert np.linalg.norm(local) == pytest.approx(0.033, abs=1e-5)
    assert force_closure(result.points, result.normals)


@pytest.mark.parametrize("fixture", ["panda_grasp", "sdh_grasp"])
def test_fingers_close_fully_without_the_object(
    fixture: str, request: pytest.FixtureRequest
) -> None:
    """With the object far from the hand, every closing joint reaches its closed value
    and nothing is touched."""
    problem, q = request.getfixturevalue(fixture)
    away = displaced(problem, 0.0, 3.0)
    result = close_hand(away, q)
    closed = closed_configuration(problem)
    moving = [
        name
        for name, value, start in zip(
            problem.robot.spec.hand_joints, closed, q[problem.robot.hand_idx], strict=False
        )
        if not np.isnan(value) and abs(value - start) > 1e-12
    ]
    assert result.contacts == ()
    assert set(result.closed_fully) == set(moving) and moving
    np.testing.assert_allclose(
        result.hand, np.where(np.isnan(closed), q[problem.robot.hand_idx][: len(closed)], closed)
    )


def test_sdh_wraps_the_can_in_force_closure(sdh_grasp: tuple[oo.Problem, np.ndarray]) -> None:
    """At the nominal pose the three fingers of the SDH all touch the can, which they
    hold in force closure and enclose; the thumb opposes fingers 1 and 2."""
    problem, q = sdh_grasp
    result = close_hand(problem, q)
    assert problem.object is not None
    fingers = {link.split("_")[1] for link in result.fingers}
    assert fingers == {"finger1", "finger2", "thumb"}
    assert force_closure(result.points, result.normals)
    assert enclosed(result.normals, object_axis(problem.object))
    thumb = [c.normal for c in result.contacts if "thumb" in c.link]
    others = [c.normal for c in result.contacts if "thumb" not in c.link]
    assert max(float(a @ b) for a in thumb for b in others) < 0  # they push against each other


def test_an_obstacle_stops_a_finger(panda_grasp: tuple[oo.Problem, np.ndarray]) -> None:
    """A box beside the can stops the finger that meets it first; its contact is
    reported apart from the object's."""
    problem, q = panda_grasp
    result = close_hand(problem, q)
    left = next(c for c in result.contacts if "left" in c.link)
    block = oo.Shape(
        "block", "box", np.r_[left.point - 0.002 * left.normal, 0, 0, 0, 1], size=np.full(3, 0.002)
    )
    blocked = close_hand(dataclasses.replace(problem, obstacles=[*problem.obstacles, block]), q)
    assert [c.shape for c in blocked.obstacle_contacts] == ["block"]
    assert all(0 < c.distance <= TOLERANCE for c in blocked.obstacle_contacts)
    assert not any("left" in c.link for c in blocked.contacts)


def _ring(angles_deg: list[float], radius: float = 0.03, z: list[float] | None = None):  # type: ignore[no-untyped-def]
    """Contacts on a vertical cylinder (or a sphere's equator) at these angles, pushing
    towards the axis."""
    a = np.radians(angles_deg)
    heights = np.zeros(a.size) if z is None else np.asarray(z)
    points = np.stack([radius * np.cos(a), radius * np.sin(a), heights], axis=1)
    normals = -np.stack([np.cos(a), np.sin(a), np.zeros(a.size)], axis=1)
    return points, normals


def test_force_closure_true_for_an_enclosing_three_finger_grasp() -> None:
    """Three fingers 120 degrees apart around a cylinder, at one height: force closure
    (friction 0.5) and enclosed."""
    points, normals = _ring([0, 120, 240])
    assert force_closure(points, normals, friction=0.5)
    assert enclosed(normals, [0, 0, 1])


def test_force_closure_false_for_two_fingers_on_the_same_side() -> None:
    """Two fingers pushing from the same side of a cylinder: neither force closure nor
    enclosure, whatever the friction."""
    points, normals = _ring([0, 10], z=[0.03, -0.03])
    for mu in (0.5, 1.0, 3.0):
        assert not force_closure(points, normals, friction=mu)
    assert not enclosed(normals, [0, 0, 1])


def test_soft_fingers_hold_an_antipodal_pinch() -> None:
    """Two opposed point contacts never reach force closure (nothing resists a turn
    about the line through them); as soft fingers with torsional friction they do."""
    points, normals = _ring([0, 180])
    for mu in (0.5, 2.0):
        assert not force_closure(points, normals, friction=mu)
        assert force_closure(points, normals, friction=mu, torsion=0.002)
    assert not force_closure(points, normals, friction=0.0, torsion=0.002)  # no friction
    with pytest.raises(ConfigError, match="torsion"):
        force_closure(points, normals, torsion=-0.001)


def test_panda_pinch_is_in_force_closure_with_its_pads(
    panda_grasp: tuple[oo.Problem, np.ndarray],
) -> None:
    """The Panda's two pads on the can: force closure with the robot file's torsional
    friction, not with point contacts."""
    problem, q = panda_grasp
    result = close_hand(problem, q)
    assert len(result.fingers) == 2
    torsion = problem.robot.spec.torsion
    assert torsion > 0
    assert force_closure(result.points, result.normals, torsion=torsion)
    assert not force_closure(result.points, result.normals)


def test_force_closure_matches_the_hand_computed_threshold() -> None:
    """Three contacts on a sphere's equator at 0 and +-beta: the normals pass through the
    centre, so force closure needs the friction cones (half-angle atan(mu)) to leave no
    gap of 180 degrees in the plane: beta > 90 deg - atan(mu) (for beta < 120 deg), and
    torques about the vertical come from friction alone (mu > 0)."""
    for mu in (0.3, 0.5, 1.0):
        threshold = 90.0 - math.degrees(math.atan(mu))
        for beta, expected in ((threshold - 2, False), (threshold + 2, True)):
            points, normals = _ring([0, beta, -beta])
            assert force_closure(points, normals, friction=mu) is expected, (mu, beta)
    points, normals = _ring([0, 120, 240])
    assert not force_closure(points, normals, friction=0.0)  # frictionless: no torque


def _in_hull_interior(wrenches: np.ndarray) -> bool:
    """The origin strictly inside the convex hull of the columns (Qhull)."""
    try:
        hull = ConvexHull(wrenches.T)
    except QhullError:
        return False  # not full-dimensional
    return bool(np.all(hull.equations[:, -1] < -1e-9))


def test_force_closure_agrees_with_the_convex_hull() -> None:
    """The linear program and Qhull's convex hull of the wrenches agree on random
    contact sets (2 to 5 contacts on a sphere, random friction)."""
    from openup_ompl.grasp import contact_wrenches

    rng = np.random.default_rng(3)
    verdicts = []
    for _ in range(60):
        k = int(rng.integers(2, 6))
        directions = rng.normal(size=(k, 3))
        directions /= np.linalg.norm(directions, axis=1, keepdims=True)
        mu = float(rng.uniform(0.1, 1.0))
        lp = force_closure(0.04 * directions, -directions, friction=mu, edges=6)
        wrenches = contact_wrenches(0.04 * directions, -directions, friction=mu, edges=6)
        assert lp == _in_hull_interior(wrenches)
        verdicts.append(lp)
    assert 5 < sum(verdicts) < 55  # both answers occur


def test_grasp_errors_are_typed(panda_grasp: tuple[oo.Problem, np.ndarray]) -> None:
    """Bad contacts, friction or options raise ConfigError; a scene without an object
    or a robot without hand joints raises InvalidProblem."""
    points, normals = _ring([0, 120, 240])
    with pytest.raises(ConfigError, match="normals"):
        force_closure(points, normals[:2])
    with pytest.raises(ConfigError, match="non-zero"):
        force_closure(points, np.zeros((3, 3)))
    with pytest.raises(ConfigError, match="friction"):
        force_closure(points, normals, friction=-0.1)
    with pytest.raises(ConfigError, match="tolerance"):
        ClosingOptions(tolerance=0.0)
    problem, q = panda_grasp
    with pytest.raises(InvalidProblem, match="object"):
        HandCloser(dataclasses.replace(problem, object=None))
    with pytest.raises(ConfigError, match="full configuration"):
        close_hand(problem, q[:3])


def test_robot_without_hand_joints_is_refused(tmp_path, panda_toml: str) -> None:  # type: ignore[no-untyped-def]
    """A robot file with no hand joints is refused with a ConfigError naming the key."""
    text = panda_toml.replace(
        'hand_joints = ["panda_finger_joint1", "panda_finger_joint2"]', "hand_joints = []"
    )
    text = "\n".join(
        line for line in text.splitlines() if not line.startswith(("c =", "b =", "w ="))
    )
    text += "\nc = []\nb = []\nw = []\n"
    robot_file = tmp_path / "armonly.toml"
    robot_file.write_text(text.replace('name = "panda"', 'name = "armonly"'))
    scene = tmp_path / "scene.toml"
    scene.write_text(
        f'robot = "{robot_file}"\n[grasp]\npose = [0.6, 0.0, 0.3, 1.0, 0.0, 0.0, 0.0]\n'
        '[object]\nname = "can"\nshape = "sphere"\nradius = 0.03\n'
        "pose = [0.6, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0]\n"
    )
    with pytest.raises(ConfigError, match="hand_joints"):
        oo.load_scene(scene)


def test_enclosed_and_force_closure_refuse_a_bad_axis_or_centre():
    """An axis that is not a finite non-zero 3-vector, or a torque centre that is not a
    finite point, is a ConfigError (they returned False, or raised numpy's LinAlgError)."""
    normals = np.array([[1.0, 0.0, 0.0], [-1.0, 0.1, 0.0], [0.0, -1.0, 0.0]])
    points = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    assert enclosed(normals, [0.0, 0.0, 1.0])
    for axis in ([0.0, 1.0], [0.0, 0.0, 0.0], [math.nan, 0.0, 1.0], "z"):
        with pytest.raises(ConfigError, match="enclosed: axis"):
            enclosed(normals, axis)
    with pytest.raises(ConfigError, match="center"):
        force_closure(points, normals, center=[math.nan] * 3)
    for name, value in (("friction", "a"), ("torsion", None)):
        with pytest.raises(ConfigError, match=name):
            force_closure(points, normals, **{name: value})
