"""Contact pads (a robot file's ``[physics] pads``): physics-only finger geometry.

The two-finger reproduction (formerly ``benchmarks/physics_edge_contact.py``): two Panda
fingers on a lifting hand close on a free can displaced across their pads, squeeze it and
lift it, with the physics world's settings.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

import openup_ompl as ou
from openup_ompl.physics import PhysicsOptions, build_world
from openup_ompl.physics.pads import PAD
from openup_ompl.physics.pads import add_pads as _add_pads
from openup_ompl.robot_file import PadSpec, RobotSpec, find_robot_file

mujoco = pytest.importorskip("mujoco")
sys.path.insert(0, str(Path(__file__).resolve().parent))

import physics_regression as regression  # noqa: E402

#: The Panda URDF's fingertip collision box (left finger frame): full sides and centre [m].
URDF_TIP = PadSpec(link="", shape="box", size=np.array([0.0175, 0.0152, 0.0185]),
                   pose=np.array([0.0, 0.00758, 0.04525, 0.0, 0.0, 0.0, 1.0]))  # fmt: skip
#: The can: the demo's (radius 30 mm, 0.1 kg).
RADIUS, HEIGHT = 0.03, 0.12


def _squeeze(pads: list[PadSpec], offset: float) -> tuple[float, float]:
    """Close two fingers carrying ``pads`` (left finger frame, mirrored in y on the right
    one) on a can whose axis is ``offset`` [m] across them, squeeze, lift the hand 10 cm
    and hold, with the physics world's settings; returns the can's final distance [m] from
    where the lift would take it and the largest angle [deg] of a finger-can contact normal
    from the closing axis."""
    options = PhysicsOptions()
    spec = mujoco.MjSpec()
    spec.option.timestep = options.timestep
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    spec.option.impratio = options.impratio
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[1, 1, 0.1])
    can = spec.worldbody.add_body(name="can", pos=[offset, 0.0, HEIGHT / 2])
    can.add_freejoint()
    can.add_geom(
        type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[RADIUS, HEIGHT / 2, 0], mass=0.1,
        friction=[0.6, 0.005, 0.0001], condim=4, priority=1,
        solref=[options.contact_timeconst, 1], solimp=list(options.contact_solimp),
    )  # fmt: skip
    # The hand: a body on a vertical slide (the lift), the fingers' pads at 44.5 mm below
    # it along the URDF finger frames' z (here the can's upper part).
    hand = spec.worldbody.add_body(name="hand", pos=[0.0, 0.0, HEIGHT - 0.03 - 0.0445],
                                   mass=1.0, inertia=[1e-3] * 3, explicitinertial=True)  # fmt: skip
    hand.add_joint(name="lift", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[0, 0, 1], armature=0.1)
    _servo(spec, "lift", options.arm_kp * 10, options.arm_kv * 10, 200.0)
    for name, side in (("left", 1.0), ("right", -1.0)):
        body = hand.add_body(name=name, mass=0.015, inertia=[2.4e-6, 2.4e-6, 7.5e-7],
                             explicitinertial=True)  # fmt: skip
        body.add_joint(name=name, type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[0, side, 0],
                       armature=options.hand_armature)  # fmt: skip
        mirrored = [
            PadSpec(link=name, shape=p.shape, size=p.size,
                    pose=p.pose * np.array([1, side, 1, 1, 1, 1, 1]))
            for p in pads
        ]  # fmt: skip
        _add_pads(spec, tuple(mirrored), options)
        _servo(spec, name, options.finger_kp, options.finger_kv, options.squeeze_force)
    spec.option.gravity = [0, 0, -9.81]
    model = spec.compile()
    data = mujoco.MjData(model)
    fingers = [model.joint(n).qposadr[0] for n in ("left", "right")]
    start = 0.045  # each finger 45 mm from the can's centre plane
    data.qpos[fingers] = start
    data.ctrl[:] = [0.0, start, start]
    angle = 0.0
    dt = options.timestep
    for k in range(3000):  # closing at 50 mm/s for 1.5 s, lift 10 cm in 1 s, hold 0.5 s
        t = k * dt
        data.ctrl[1:] = max(0.0, start - options.finger_close_speed * t)
        data.ctrl[0] = min(0.1, max(0.0, (t - 1.5) * 0.1))
        mujoco.mj_step(model, data)
        for i in range(data.ncon):
            if 0 not in data.contact.geom[i]:
                normal = data.contact.frame[i][:3]
                angle = max(angle, float(np.degrees(np.arccos(min(1.0, abs(normal[1]))))))
    lifted = np.array([offset, 0.0, HEIGHT / 2 + data.qpos[model.joint("lift").qposadr[0]]])
    return float(np.linalg.norm(data.qpos[:3] - lifted)), angle


def _servo(spec: object, joint: str, kp: float, kv: float, force: float) -> None:
    """A position actuator on ``joint``."""
    actuator = spec.add_actuator(name=joint, target=joint, trntype=mujoco.mjtTrn.mjTRN_JOINT)
    actuator.gainprm[0] = kp
    actuator.biastype = mujoco.mjtBias.mjBIAS_AFFINE
    actuator.biasprm[:3] = [0.0, -kp, -kv]
    actuator.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
    actuator.forcerange = [-force, force]


def _panda_pads() -> list[PadSpec]:
    """The shipped Panda's left-finger pads."""
    spec = RobotSpec.from_file(find_robot_file("panda"))
    return [p for p in spec.pads if p.link == "panda_leftfinger"]


@pytest.mark.parametrize("offset", [0.0, 0.01, 0.015, -0.015])
def test_the_pads_hold_a_can_displaced_across_them(offset):
    """Two Panda fingers with the robot file's pads close on a can up to 1.5 cm across
    them, squeeze and lift it 10 cm: it ends within 5 mm of where the hand took it."""
    moved, _ = _squeeze(_panda_pads(), offset)
    assert moved < 0.005, moved


def test_a_can_2_cm_across_is_squeezed_out_in_the_reduced_model():
    """The reduced model is not the whole story: at 2 cm across (the pad's edge 11.5 mm
    from the can's axis) the can leaves these two fingers with the pads as with the URDF's
    fingertip box, its contact normal turned past 45 deg, while the whole Panda rollout
    holds it (README, Contact pads)."""
    for pads in (_panda_pads(), [URDF_TIP]):
        moved, angle = _squeeze(pads, 0.02)
        assert moved > 0.05 and angle > 45.0, (moved, angle)


def test_the_panda_world_has_pads_and_its_fingertip_boxes_meet_only_obstacles():
    """The Panda's world has 12 pad geoms (contype 2: the object only); each finger's
    URDF fingertip box, which holds the pads' centres, meets only fixed obstacles
    (contype 1); without pads (PhysicsOptions(pads=False)) there is no pad geom."""
    data = regression.plan_contents(regression.load()[0])
    model = build_world(data).model
    names = [model.geom(g).name for g in range(model.ngeom)]
    pads = [g for g, n in enumerate(names) if n.startswith(PAD)]
    assert len(pads) == 12
    assert set(model.geom_contype[pads]) == {2}
    assert model.body("panda_leftfinger").mass[0] == pytest.approx(0.015)  # massless pads
    for finger in ("panda_leftfinger", "panda_rightfinger"):
        body = model.body(finger).id
        tips = [g for g in np.flatnonzero(model.geom_bodyid == body)
                if g not in pads and model.geom_contype[g] == 1]  # fmt: skip
        assert len(tips) == 1
        assert model.geom_size[tips[0]] == pytest.approx([0.00875, 0.0076, 0.00925])
    plain = build_world(data, PhysicsOptions(pads=False)).model
    assert not any(plain.geom(g).name.startswith(PAD) for g in range(plain.ngeom))


@pytest.mark.parametrize(
    ("pad", "match"),
    [
        ({"link": "l", "shape": "cone", "pose": [0, 0, 0, 0, 0, 0, 1]}, "shape"),
        ({"link": "l", "shape": "box", "pose": [0, 0, 0, 0, 0, 0, 1]}, "size"),
        ({"link": "l", "shape": "box", "size": [0.01, 0.01, 2.0],
          "pose": [0, 0, 0, 0, 0, 0, 1]}, "size"),
        ({"link": "l", "shape": "sphere", "radius": 0.01, "size": [0.01, 0.01, 0.01],
          "pose": [0, 0, 0, 0, 0, 0, 1]}, "size"),
        ({"link": "l", "shape": "sphere", "radius": 0.01, "pose": [0, 0, 0, 0, 0, 0, 1],
          "solimp": [0.99, 0.95, 0.001]}, "solimp"),
    ],
)  # fmt: skip
def test_bad_pads_are_refused_naming_the_key(tmp_path, panda_toml, pad, match):
    """A pad of an unknown shape, without its size, too large, with another shape's key,
    or a solimp whose d0 exceeds dwidth is a ConfigError naming it."""
    import tomllib

    text = panda_toml.split("[physics]")[0]
    urdf = tomllib.loads(panda_toml)["urdf"]
    inline = ", ".join(f"{k} = {v!r}".replace("'", '"') for k, v in pad.items())
    path = tmp_path / "robot.toml"
    path.write_text(text.replace(urdf, urdf) + f"\n[physics]\npads = [{{ {inline} }}]\n")
    with pytest.raises(ou.ConfigError, match=match):
        RobotSpec.from_file(path)


def test_a_pad_on_a_missing_link_is_refused_when_the_world_is_built():
    """A pad naming a link the URDF lacks is a ConfigError naming the link."""
    from dataclasses import replace

    from openup_ompl.physics.world import RobotTable, make_world
    from openup_ompl.scene import Shape

    data = regression.plan_contents(regression.load()[0])
    robot = RobotTable.from_table(data["robot"])
    bad = replace(robot, pads=(replace(robot.pads[0], link="no_such_link"),))
    can = Shape.from_table(data["scene"]["object"], "object", is_object=True)
    with pytest.raises(ou.ConfigError, match="no_such_link"):
        make_world(bad, [], can)
