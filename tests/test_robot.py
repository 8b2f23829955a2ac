"""Robot files (CONTRACT §1) loaded into Pinocchio and Coal."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import openup_ompl as ou
from openup_ompl.collision import CollisionWorld

ARM = [f"panda_joint{i}" for i in range(1, 8)]
HAND = ["panda_finger_joint1", "panda_finger_joint2"]


def test_panda_loads_with_its_file_contents(panda):
    """The shipped Panda loads with the joints, palm frame and home of robots/panda.toml."""
    assert panda.name == "panda"
    assert "panda" in ou.available_robots()
    assert list(panda.spec.arm_joints) == ARM
    assert list(panda.spec.hand_joints) == HAND
    assert panda.spec.palm_frame == "panda_hand"
    np.testing.assert_allclose(panda.spec.home, [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
    assert panda.spec.srdf is not None and panda.spec.srdf.is_file()
    assert panda.spec.urdf.is_file()


def test_joint_lists_resolve_to_their_q_indices(panda):
    """arm_idx and hand_idx are the joints' idx_q in Pinocchio's model, in file order."""
    model = panda.model
    expected_arm = [model.joints[model.getJointId(name)].idx_q for name in ARM]
    expected_hand = [model.joints[model.getJointId(name)].idx_q for name in HAND]
    assert panda.arm_idx.tolist() == expected_arm
    assert panda.hand_idx.tolist() == expected_hand
    assert len(set(expected_arm) | set(expected_hand)) == 9


def test_full_q_places_arm_and_hand_at_their_indices(panda):
    """full_q puts arm and hand values where arm_idx and hand_idx say."""
    arm = np.linspace(-0.5, 0.5, 7)
    hand = np.array([0.01, 0.03])
    q = panda.full_q(arm, hand)
    assert q.shape == (panda.model.nq,)
    np.testing.assert_array_equal(q[panda.arm_idx], arm)
    np.testing.assert_array_equal(q[panda.hand_idx], hand)


def test_joint_names_follow_q_order(panda):
    """joint_names lists every configured joint in Pinocchio's q order."""
    names = panda.joint_names
    assert names == ARM + HAND
    idx_q = [panda.model.joints[panda.model.getJointId(n)].idx_q for n in names]
    assert idx_q == sorted(idx_q)


def test_palm_frame_resolves(panda):
    """The palm frame id is Pinocchio's id of panda_hand and FK gives its placement."""
    assert panda.palm_frame_id == panda.model.getFrameId("panda_hand")
    assert panda.model.frames[panda.palm_frame_id].name == "panda_hand"
    data = panda.model.createData()
    q = panda.full_q(panda.spec.home, np.zeros(2))
    placement = panda.palm_placement(data, q)
    pin.framesForwardKinematics(panda.model, data, q)
    assert placement.isApprox(data.oMf[panda.palm_frame_id])


def test_home_is_collision_free(panda, empty_scene_text, write_file):
    """The home configuration, hand at its law value, collides with nothing."""
    problem = ou.load_scene(write_file("empty.toml", empty_scene_text), robot=panda)
    np.testing.assert_array_equal(problem.start, panda.spec.home)
    world = CollisionWorld(problem, num_threads=1)
    hand = problem.hand_law(1.0)
    assert not world.in_collision(panda.full_q(panda.spec.home, hand))


def test_collision_world_detects_an_obstacle_at_the_palm(panda, empty_scene_text, write_file):
    """A sphere placed on the palm at home makes home collide (the check is not vacuous)."""
    data = panda.model.createData()
    palm = panda.palm_placement(data, panda.full_q(panda.spec.home, np.zeros(2))).translation
    scene = empty_scene_text + (
        "[[obstacles]]\n"
        'name = "ball"\nshape = "sphere"\nradius = 0.05\n'
        f"pose = [{palm[0]}, {palm[1]}, {palm[2]}, 0.0, 0.0, 0.0, 1.0]\n"
    )
    problem = ou.load_scene(write_file("ball.toml", scene), robot=panda)
    world = CollisionWorld(problem, num_threads=1)
    q = panda.full_q(panda.spec.home, problem.hand_law(1.0))
    assert world.in_collision(q)
    assert any("env/ball" in pair for pair in world.colliding_pairs(q))
    assert world.touches_environment(q)


def test_touches_environment_tells_the_scene_from_the_robot_itself(
    panda, default_scene_text, write_file
):
    """``touches_environment`` is true exactly where a colliding pair names an obstacle or
    the object, on random Panda states of the demo scene: among them states that collide
    with the scene, and states that collide with the robot only."""
    problem = ou.load_scene(write_file("scene.toml", default_scene_text), robot=panda)
    world = CollisionWorld(problem, num_threads=1)
    rng = np.random.default_rng(5)
    kinds = set()
    for _ in range(300):
        q = panda.full_q(rng.uniform(panda.arm_lower, panda.arm_upper), problem.hand_law(1.0))
        pairs = world.colliding_pairs(q)
        scene = any(name.startswith("env/") for pair in pairs for name in pair)
        assert world.touches_environment(q) == scene
        kinds.add((bool(pairs), scene))
    assert kinds == {(False, False), (True, False), (True, True)}


def test_srdf_prunes_self_collision_pairs(panda):
    """The SRDF removes pairs: fewer collision pairs than addAllCollisionPairs gives."""
    full = pin.buildGeomFromUrdf(
        panda.model, str(panda.spec.urdf), pin.COLLISION, package_dirs=panda.package_dirs
    )
    full.addAllCollisionPairs()
    pruned = len(panda.collision_model.collisionPairs)
    assert full.ngeoms == panda.collision_model.ngeoms
    assert 0 < pruned < len(full.collisionPairs)


def test_unknown_robot_name_raises_robot_not_found():
    """An unknown robot name raises RobotNotFound naming it and listing the robots."""
    with pytest.raises(ou.RobotNotFound, match="no_such_robot") as info:
        ou.load_robot("no_such_robot")
    assert info.value.name == "no_such_robot"
    assert "panda" in info.value.available


def test_robot_loads_from_a_copied_file(panda_toml, write_file):
    """A copy of panda.toml elsewhere loads (example-robot-data:// works from any directory)."""
    robot = ou.load_robot(write_file("copy.toml", panda_toml))
    assert robot.spec.arm_joints == tuple(ARM)


def test_wrong_joint_name_raises_joint_not_found(panda_toml, write_file):
    """A joint the URDF lacks raises JointNotFound naming it."""
    path = write_file("bad.toml", panda_toml.replace('"panda_joint3"', '"panda_joint33"'))
    with pytest.raises(ou.JointNotFound, match="panda_joint33") as info:
        ou.load_robot(path)
    assert info.value.name == "panda_joint33"
    assert "panda_joint3" in info.value.joints


def test_missing_urdf_raises_config_error_naming_the_path(panda_toml, write_file):
    """A URDF path that does not exist raises ConfigError naming that path."""
    text = panda_toml.replace(
        'urdf = "example-robot-data://panda_description/urdf/panda.urdf"',
        'urdf = "nowhere/missing.urdf"',
    )
    assert "nowhere/missing.urdf" in text
    with pytest.raises(ou.ConfigError, match="nowhere/missing.urdf") as info:
        ou.load_robot(write_file("bad.toml", text))
    assert "urdf" in info.value.where


def test_c_of_wrong_length_raises_config_error_naming_hand_c(panda_toml, write_file):
    """A close preshape with the wrong number of values raises ConfigError naming hand.c."""
    text = panda_toml.replace("c = [0.02, 0.02]", "c = [0.02, 0.02, 0.02]")
    with pytest.raises(ou.ConfigError, match=r"hand\.c") as info:
        ou.load_robot(write_file("bad.toml", text))
    assert "bad.toml" in str(info.value)


def test_unknown_hand_key_names_the_nearest_valid_one(panda_toml, write_file):
    """A typo in the robot file's [hand] table is refused like one in a scene's (it was
    ignored: `torsoin = 0.002` left the torsion at 0)."""
    text = panda_toml.replace("torsion = 0.002", "torsoin = 0.002")
    with pytest.raises(ou.ConfigError, match=r"hand\.torsoin.*did you mean 'torsion'"):
        ou.load_robot(write_file("typo.toml", text))


def test_unknown_palm_frame_raises_frame_not_found(panda_toml, write_file):
    """A palm frame the URDF lacks raises FrameNotFound naming it."""
    text = panda_toml.replace('palm_frame = "panda_hand"', 'palm_frame = "panda_palm"')
    with pytest.raises(ou.FrameNotFound, match="panda_palm") as info:
        ou.load_robot(write_file("bad.toml", text))
    assert "panda_hand" in info.value.frames


def test_home_outside_limits_raises_config_error_naming_the_joint(panda_toml, write_file):
    """A home outside the joint limits raises ConfigError naming the joint."""
    # panda_joint4's range is [-3.0718, -0.0698]: 0.5 is outside it.
    text = panda_toml.replace(
        "home = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785]",
        "home = [0.0, -0.785, 0.0, 0.5, 0.0, 1.571, 0.785]",
    )
    with pytest.raises(ou.ConfigError, match="panda_joint4") as info:
        ou.load_robot(write_file("bad.toml", text))
    assert info.value.value == 0.5


@pytest.mark.parametrize("value", ["[0.0, 0.0, 0.0]", "[1.0, 0.0]", '"z"'])
def test_bad_approach_raises_config_error_naming_it(panda_toml, write_file, value):
    """A zero, short or non-numeric approach axis raises ConfigError naming approach."""
    text = panda_toml.replace("approach = [0.0, 0.0, 1.0]", f"approach = {value}")
    assert f"approach = {value}" in text
    with pytest.raises(ou.ConfigError, match="approach"):
        ou.load_robot(write_file("bad.toml", text))


def test_approach_is_normalised(panda_toml, write_file):
    text = panda_toml.replace("approach = [0.0, 0.0, 1.0]", "approach = [0.0, 3.0, 4.0]")
    robot = ou.load_robot(write_file("axis.toml", text))
    np.testing.assert_allclose(robot.spec.approach, [0.0, 0.6, 0.8])
