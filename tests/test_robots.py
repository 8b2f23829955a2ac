"""Shipped robots (parametrised over ``available_robots()``), the extended robot format
(``[mount]``, ``[mimic]``, ``padding``) and its typed errors, and the robots' demo scenes."""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from recheck import solved_and_rechecked

import openup_ompl as oo
from openup_ompl._resources import data_dir
from openup_ompl.collision import CollisionWorld
from openup_ompl.exceptions import ConfigError, FrameNotFound, JointNotFound

ROBOTS = sorted(oo.available_robots())
DEMO_SCENES = sorted(
    path
    for name in ROBOTS
    if name != "panda"  # the Panda's scenes are covered by test_planning.py
    for path in data_dir("scenes").glob(f"{name}_*.toml")
)
SEEDS = range(20)
#: A grasp pose at the origin with the identity rotation (the problem is only checked).
IDENTITY = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]


@pytest.fixture(scope="module", params=ROBOTS)
def robot(request: pytest.FixtureRequest) -> oo.Robot:
    """Each shipped robot, loaded once."""
    return oo.load_robot(request.param)


def _free_world(robot: oo.Robot) -> CollisionWorld:
    problem = oo.Problem(robot, robot.spec.home, IDENTITY, robot.hand_law(), [], None)
    return CollisionWorld(problem, environment=[])


def test_robot_loads_and_names_resolve(robot: oo.Robot) -> None:
    """Arm and hand joints are one-DOF joints of the model; the palm frame exists."""
    names = robot.joint_names
    assert set(robot.spec.arm_joints) <= set(names)
    assert set(robot.hand_joints) <= set(names)
    assert robot.hand_joints[: robot.n_driven] == robot.spec.hand_joints
    assert robot.model.frames[robot.palm_frame_id].name == robot.spec.palm_frame
    assert len(set(robot.arm_idx) | set(robot.hand_idx)) == robot.arm_idx.size + robot.hand_idx.size
    assert robot.urdf is not None and robot.urdf.is_file()


@pytest.mark.parametrize("hand", ["home", "c", "b", "w"])
def test_collision_free_in_free_space(robot: oo.Robot, hand: str) -> None:
    """At home, with the hand at b (home) or at c, b, w, the robot does not self-collide."""
    values = robot.spec.b if hand == "home" else getattr(robot.spec, hand)
    q = robot.full_q(robot.spec.home, values)
    world = _free_world(robot)
    assert not world.in_collision(q), world.colliding_pairs(q)


def test_law_follows_mimic(robot: oo.Robot) -> None:
    """Every follower of the law is multiplier * leader + offset (inside its limits)."""
    law = robot.hand_law()
    driven = list(robot.spec.hand_joints)
    for d in np.linspace(0.0, 1.0, 11):
        hand = law(float(d))
        for k, mimic in enumerate(robot.mimic):
            expected = mimic.multiplier * hand[driven.index(mimic.leader)] + mimic.offset
            low, high = law.lower[robot.n_driven + k], law.upper[robot.n_driven + k]
            assert hand[robot.n_driven + k] == pytest.approx(np.clip(expected, low, high))


def test_merged_urdf_agrees_with_composition(robot: oo.Robot) -> None:
    """Pinocchio loads the robot's URDF to the same joints and palm FK at random q."""
    model = pin.buildModelFromUrdf(str(robot.urdf))
    names = [model.names[i] for i in range(1, model.njoints) if model.joints[i].nq > 0]
    assert names == robot.joint_names
    palm = (
        model.getFrameId(robot.spec.palm_frame, pin.FrameType.BODY)
        if model.existFrame(robot.spec.palm_frame, pin.FrameType.BODY)
        else model.getFrameId(robot.spec.palm_frame)
    )
    data, ours = model.createData(), robot.model.createData()
    rng = np.random.default_rng(0)
    low, high = robot.model.lowerPositionLimit, robot.model.upperPositionLimit
    for _ in range(10):
        q = rng.uniform(np.maximum(low, -3.0), np.minimum(high, 3.0))
        pin.forwardKinematics(model, data, q)
        theirs = pin.updateFramePlacement(model, data, palm)
        assert np.allclose(theirs.homogeneous, robot.palm_placement(ours, q).homogeneous)


# --- the format, on small robot files written here -------------------------------------

UR5 = "example-robot-data://ur_description/urdf/ur5_joint_limited_robot.urdf"
ALLEGRO = "example-robot-data://allegro_hand_description/urdf/allegro_right_hand.urdf"
UR5_ARM = '["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", ' + (
    '"wrist_2_joint", "wrist_3_joint"]'
)


def _composite(
    hand_joints: str = '["joint_0.0", "joint_1.0"]',
    c: str = "[0.0, 0.1]",
    frame: str = "tool0",
    extra: str = "",
    mimic: str = "",
) -> str:
    return f"""name = "test_composite"
urdf = "{UR5}"
palm_frame = "palm_link"
arm_joints = {UR5_ARM}
hand_joints = {hand_joints}
home = [0.0, -1.571, 1.571, -1.571, -1.571, 0.0]
{extra}
[mount]
urdf = "{ALLEGRO}"
frame = "{frame}"
pose = [0.0, 0.0, 0.095, 0.0, 0.0, 0.0, 1.0]
[hand]
c = {c}
b = [0.0, 0.2]
w = [0.0, 0.3]
mga = 0.25
{mimic}"""


#: The Allegro's thumb base, which the composite robot does not drive: held inside its
#: limits [0.263, 1.396] by a [mimic] row that ignores its leader.
HOLD_THUMB_BASE = '"joint_12.0" = { joint = "joint_0.0", multiplier = 0.0, offset = 0.3 }\n'


def test_mimic_table_expands_law(write_file: Callable[[str, str], Path]) -> None:
    """[mimic] followers join hand_idx after the driven joints and follow their leader."""
    mimic = (
        '[mimic]\n"joint_5.0" = { joint = "joint_1.0", multiplier = 0.5, offset = 0.1 }\n'
        '"joint_9.0" = { joint = "joint_1.0" }\n' + HOLD_THUMB_BASE
    )
    robot = oo.load_robot(write_file("r.toml", _composite(mimic=mimic)))
    assert robot.hand_joints == ("joint_0.0", "joint_1.0", "joint_5.0", "joint_9.0", "joint_12.0")
    law = robot.hand_law()
    assert law.c.tolist() == pytest.approx([0.0, 0.1, 0.15, 0.1, 0.3])
    assert law.w.tolist() == pytest.approx([0.0, 0.3, 0.25, 0.3, 0.3])
    q = robot.full_q(robot.spec.home, [0.0, 0.4])
    assert q[robot.hand_idx].tolist() == pytest.approx([0.0, 0.4, 0.3, 0.4, 0.3])


def test_a_joint_held_outside_its_limits_is_refused(
    write_file: Callable[[str, str], Path],
) -> None:
    """The Allegro's thumb base (limits [0.263, 1.396]) left out of the hand joints was
    held at 0, outside its limits, and every plan then refused by show and execute."""
    with pytest.raises(ConfigError, match=re.escape("joint_12.0")):
        oo.load_robot(write_file("r.toml", _composite()))


def test_mount_prefix_renames_hand(write_file: Callable[[str, str], Path]) -> None:
    """With a prefix, the hand's joints and links carry it in the model and merged URDF."""
    text = _composite(hand_joints='["h_joint_0.0", "h_joint_1.0"]').replace(
        'palm_frame = "palm_link"', 'palm_frame = "h_palm_link"'
    )
    text = text.replace("[hand]", 'prefix = "h_"\n[hand]') + HOLD_THUMB_BASE.replace(
        "joint_", "h_joint_"
    ).replace("[mimic]", "")
    text = text.replace("mga = 0.25\n", "mga = 0.25\n[mimic]\n")
    robot = oo.load_robot(write_file("r.toml", text))
    assert robot.joint_names[6:8] == ["h_joint_0.0", "h_joint_1.0"]
    model = pin.buildModelFromUrdf(str(robot.urdf))
    assert [model.names[i] for i in range(1, model.njoints)] == robot.joint_names


def test_urdf_mimic_tags_of_unlisted_joints(write_file: Callable[[str, str], Path]) -> None:
    """A URDF <mimic> of a joint not in the robot file makes it a follower; the Panda's
    listed finger_joint2 stays independent."""
    panda = oo.load_robot("panda")
    assert panda.mimic == ()
    assert panda.hand_joints == ("panda_finger_joint1", "panda_finger_joint2")
    text = oo.available_robots()["panda"].read_text()
    text = text.replace(
        'hand_joints = ["panda_finger_joint1", "panda_finger_joint2"]',
        'hand_joints = ["panda_finger_joint1"]',
    )
    text = re.sub(r"\[0\.0(\d+), 0\.0\d+\]", r"[0.0\1]", text)
    robot = oo.load_robot(write_file("p.toml", text))
    assert robot.hand_joints == ("panda_finger_joint1", "panda_finger_joint2")
    assert robot.hand_law().c.tolist() == pytest.approx([0.02, 0.02])


def test_padding_grows_environment(write_file: Callable[[str, str], Path]) -> None:
    """The robot's padding is added, unhalved, to the checker's padding of every shape."""
    text = (
        oo.available_robots()["panda"]
        .read_text()
        .replace("convex = true", "convex = true\npadding = 0.05")
    )
    robot = oo.load_robot(write_file("p.toml", text))
    assert robot.spec.padding == 0.05
    ball = oo.Shape("ball", "sphere", np.array([2.0, 0, 0, 0, 0, 0, 1.0]), radius=0.01)
    problem = oo.Problem(robot, robot.spec.home, IDENTITY, robot.hand_law(), [ball], None)
    for padding in (0.0, 0.004):
        world = CollisionWorld(problem, padding=padding)
        grown = world.geometry_model.geometryObjects[-1].geometry
        assert grown.radius == pytest.approx(0.01 + 0.05 + padding)


@pytest.mark.parametrize(
    ("kwargs", "error", "named"),
    [
        ({"hand_joints": '["joint_0.0", "no_such_joint"]'}, JointNotFound, "no_such_joint"),
        ({"c": "[0.0, 0.1, 0.2]"}, ConfigError, "hand.c"),
        ({"frame": "no_such_frame"}, FrameNotFound, "no_such_frame"),
        (
            {"mimic": '[mimic]\n"joint_5.0" = { joint = "joint_7.0" }\n'},
            ConfigError,
            "joint_7.0",
        ),
        (
            {"mimic": '[mimic]\n"joint_5.0" = { joint = "ghost", multiplier = 1.0 }\n'},
            ConfigError,
            "ghost",
        ),
        ({"extra": "padding = -0.01"}, ConfigError, "padding"),
    ],
)
def test_bad_robot_file_is_a_typed_error(
    write_file: Callable[[str, str], Path],
    kwargs: dict[str, str],
    error: type[Exception],
    named: str,
) -> None:
    """Wrong joint, c of the wrong length, missing mount frame, bad mimic leader, bad
    padding: a typed error naming the bad value."""
    with pytest.raises(error, match=re.escape(named)):
        oo.load_robot(write_file("bad.toml", _composite(**kwargs)))


def test_missing_urdf_is_named(write_file: Callable[[str, str], Path]) -> None:
    """A missing (hand) URDF raises ConfigError naming the path."""
    text = _composite().replace(ALLEGRO, "hands/missing.urdf")
    with pytest.raises(ConfigError, match="missing.urdf"):
        oo.load_robot(write_file("bad.toml", text))


def test_bad_mount_pose_is_named(write_file: Callable[[str, str], Path]) -> None:
    """A mount pose with a non-unit quaternion raises ConfigError naming mount.pose."""
    text = _composite().replace("0.0, 0.0, 0.095, 0.0, 0.0, 0.0, 1.0", "0, 0, 0.1, 0, 0, 0, 2")
    with pytest.raises(ConfigError, match="mount.pose"):
        oo.load_robot(write_file("bad.toml", text))


# --- demo scenes -------------------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize("scene", DEMO_SCENES, ids=lambda p: p.stem)
@pytest.mark.parametrize("planner", ["ikbirrt", "rrtconnect"])
def test_demo_scene_solved_on_19_of_20_seeds(scene: Path, planner: str, tmp_path: Path) -> None:
    """Both planners solve each robot's demo scene on >= 19 of 20 seeds; every plan passes
    the independent re-check. The 60 s limit only guards against a hang: the count does
    not depend on the machine's speed or load."""
    setup = oo.GraspPlanningSetup(oo.load_scene(scene))
    assert solved_and_rechecked(setup, planner, SEEDS, 60.0, tmp_path) >= 19
