"""The physics world of a plan: its robot and scene in MuJoCo, built from the plan file alone.

The robot is the plan's URDF (``robot.urdf``, meshes found through ``package_dirs``)
loaded by MuJoCo's URDF importer with collision geometry only; URDF ``<mimic>`` tags
become joint equality constraints; URDF ``<dynamics>`` (damping, friction) are ignored.
Every arm and hand joint gets a position actuator
(:class:`~openup_ompl.physics.options.PhysicsOptions` gains; the URDF's ``effort`` as
the arm's force limit, the squeeze force or torque as the hand's), every robot body
gravity compensation (the controller of a real arm and hand cancels their weight), every
joint armature. The fixed obstacles are static geoms, the object a free body
(:func:`~openup_ompl.physics.shapes.add_scene`), and every movable obstacle (``movable =
true``: a neighbour the hand may push or tip) a free body of its own with its ``mass`` and
``friction``. :func:`build_world` assembles them in four steps: the robot, the object, the
neighbours, the contacts.

Robot geoms collide with the scene, not with each other (the planner checked
self-collision; MuJoCo's URDF importer would otherwise let neighbouring links that the
SRDF excludes push each other apart).

Numerics: the ``implicitfast`` integrator (Euler without armature drifted and dropped the
object) and the dense constraint Jacobian (``mjJAC_DENSE``: the
sparse path is never taken, see the README on MuJoCo issue 3767).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from openup_ompl.exceptions import ConfigError
from openup_ompl.physics.options import PhysicsOptions
from openup_ompl.physics.pads import add_pads, pad_contacts
from openup_ompl.physics.robot_table import RobotTable
from openup_ompl.physics.shapes import add_free_body, add_scene
from openup_ompl.physics.watch import Watch, add_watch, watch_of
from openup_ompl.scene import Shape
from openup_ompl.urdf import absolute_meshes, urdf_mimic, urdf_tree

if TYPE_CHECKING:
    import mujoco


__all__ = [
    "COMPILER",
    "RobotTable",
    "World",
    "build_world",
    "make_world",
    "plan_shapes",
    "urdf_spec",
]

#: Added to the URDF for MuJoCo's importer: keep mesh paths, drop visual geometry, accept
#: the URDFs' inertias as they are, keep every link a body (the palm frame among them).
COMPILER = (
    '<compiler strippath="false" discardvisual="true" balanceinertia="true" fusestatic="false"/>'
)

#: Geom classes of :attr:`World.geom_kind` (``NEIGHBOUR``: a movable obstacle's geom).
ROBOT, OBSTACLE, OBJECT, FIXED_ROBOT, NEIGHBOUR = 0, 1, 2, 3, 4
#: Body name prefix of a movable obstacle (``"neighbour/<shape name>"``).
NEIGHBOUR_BODY = "neighbour/"


def urdf_spec(urdf: str | Path, package_dirs: list[str]) -> tuple[mujoco.MjSpec, ET.Element]:
    """MuJoCo spec of a URDF (meshes made absolute, :data:`COMPILER` added) and its
    parsed tree.

    Args:
        urdf: The URDF file.
        package_dirs: Directories ``package://`` mesh paths are resolved in.

    Returns:
        ``(spec, root)``: the MuJoCo spec and the URDF's XML root element.

    Raises:
        ConfigError: The URDF is missing or unreadable, or MuJoCo rejects it.
    """
    import mujoco

    path = Path(urdf)
    if not path.is_file():
        raise ConfigError("plan robot.urdf", str(path), "an existing URDF file")
    root = urdf_tree(path, "plan robot.urdf")
    absolute_meshes(root, path, list(package_dirs))
    for old in root.findall("mujoco"):
        root.remove(old)
    extension = ET.SubElement(root, "mujoco")
    extension.append(ET.fromstring(COMPILER))
    try:
        spec = mujoco.MjSpec.from_string(ET.tostring(root, encoding="unicode"))
    except ValueError as error:
        raise ConfigError("plan robot.urdf", str(path), f"a URDF MuJoCo loads ({error})") from None
    return spec, root


def plan_shapes(data: dict[str, Any]) -> tuple[list[Shape], Shape]:
    """The obstacles and the object of a plan file's ``scene`` (validated as scene keys).

    Args:
        data: A plan file's contents.

    Returns:
        ``(obstacles, object)``, poses in the world frame.

    Raises:
        ConfigError: A malformed shape, or a plan with no object.
    """
    scene = data.get("scene") or {}
    raw_object = scene.get("object")
    if raw_object is None:
        raise ConfigError("plan scene.object", None, "an object to grasp")
    obstacles = [
        Shape.from_table(t, f"plan scene.obstacles[{i}]")
        for i, t in enumerate(scene.get("obstacles") or [])
    ]
    return obstacles, Shape.from_table(raw_object, "plan scene.object", is_object=True)


@dataclass(eq=False)
class World:
    """A compiled physics world and the indices a rollout needs.

    Attributes:
        model: The compiled ``mujoco.MjModel``.
        joint_names: The plan's ``joint_names`` (each path row in this order).
        qpos: ``qpos`` address of each of :attr:`joint_names`.
        dof: ``qvel`` address of each.
        actuator: Actuator index of each (``ctrl`` order).
        arm: Indices into :attr:`joint_names` of the arm joints.
        hand: Indices into :attr:`joint_names` of the hand joints (driven, then followers).
        prismatic: Per joint of :attr:`joint_names`: prismatic (True) or revolute.
        velocity_limit: URDF ``velocity`` limit per joint [rad/s or m/s]
            (:attr:`~openup_ompl.physics.options.PhysicsOptions.velocity_limit` if none).
        lower: Lower position limit per joint (``-inf`` if unlimited).
        upper: Upper position limit per joint.
        palm_body: Body index of the palm frame's link.
        object_body: Body index of the object.
        object_qpos: ``qpos`` address of the object's free joint (position, then the
            scalar-first quaternion).
        object_dof: ``qvel`` address of the free joint.
        object_geom: Geom index of the object.
        geom_kind: Per geom: :data:`ROBOT`, :data:`OBSTACLE`, :data:`OBJECT`,
            :data:`FIXED_ROBOT` (robot links welded to the world) or :data:`NEIGHBOUR`.
        geom_link: Per geom: the link (body) or shape name.
        mimic: URDF followers ``(follower, leader, multiplier, offset)`` as indices into
            :attr:`joint_names`.
        object_shape: The object as placed in the plan's scene (the nominal pose).
        neighbours: The movable obstacles (free bodies), in the scene's order.
        neighbour_body: Body index of each of :attr:`neighbours`.
        neighbour_qpos: ``qpos`` address of each one's free joint.
        neighbour_dof: ``qvel`` address of each one's free joint.
        neighbour_start: ``(k, 7)`` each one's start ``qpos`` (position, scalar-first
            quaternion): its scene pose.
        watch: Where the contact sensors of the simulation loop sit
            (:mod:`~openup_ompl.physics.watch`).
    """

    model: Any
    joint_names: list[str]
    qpos: np.ndarray
    dof: np.ndarray
    actuator: np.ndarray
    arm: np.ndarray
    hand: np.ndarray
    prismatic: np.ndarray
    velocity_limit: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    palm_body: int
    object_body: int
    object_qpos: int
    object_dof: int
    object_geom: int
    geom_kind: np.ndarray
    geom_link: list[str]
    mimic: list[tuple[int, int, float, float]]
    object_shape: Shape
    neighbours: list[Shape] = field(default_factory=list)
    neighbour_body: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.intp))
    neighbour_qpos: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.intp))
    neighbour_dof: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.intp))
    neighbour_start: np.ndarray = field(default_factory=lambda: np.zeros((0, 7)))
    watch: Watch = field(default_factory=lambda: Watch(-1, (), ()))


def _joint_limits(root: ET.Element) -> dict[str, tuple[float, float]]:
    """``joint -> (velocity, effort)`` from the URDF's ``<limit>`` tags (inf if absent)."""
    limits = {}
    for joint in root.iter("joint"):
        tag = joint.find("limit")
        velocity = effort = math.inf
        if tag is not None:
            velocity = float(tag.get("velocity", "inf")) or math.inf
            effort = float(tag.get("effort", "inf")) or math.inf
        limits[str(joint.get("name"))] = (velocity, effort)
    return limits


def build_world(data: dict[str, Any], options: PhysicsOptions | None = None) -> World:
    """The physics world of a plan file's contents (:func:`~openup_ompl.plan.read_plan`).

    Args:
        data: A plan file's contents.
        options: The physics settings (default
            :class:`~openup_ompl.physics.options.PhysicsOptions`).

    Returns:
        The world.

    Raises:
        ConfigError: A missing URDF, a joint or the palm frame absent from it, or a
            malformed scene.
    """
    obstacles, scene_object = plan_shapes(data)
    robot = RobotTable.from_table(data.get("robot") or {})
    return make_world(robot, obstacles, scene_object, options)


def make_world(
    robot: RobotTable,
    obstacles: Sequence[Shape],
    scene_object: Shape,
    options: PhysicsOptions | None = None,
) -> World:
    """The physics world of a robot and a scene: the robot, the object, the neighbours
    (movable obstacles) and the contacts between them (module docstring).

    Args:
        robot: The robot's joints, palm and URDF.
        obstacles: The scene's obstacles (movable ones become neighbours).
        scene_object: The object to grasp, at its nominal pose.
        options: The physics settings (default
            :class:`~openup_ompl.physics.options.PhysicsOptions`).

    Returns:
        The world.

    Raises:
        ConfigError: A missing URDF, a joint or the palm frame absent from it.
    """
    options = options or PhysicsOptions()
    spec, root = urdf_spec(robot.urdf, list(robot.package_dirs))
    limits = _joint_limits(root)
    _add_robot(spec, robot, limits, options)
    pads = robot.pads if options.pads else ()
    add_pads(spec, pads, options)
    if options.object_mass is not None:
        scene_object = replace(scene_object, mass=options.object_mass)
    if options.object_friction is not None:
        scene_object = replace(scene_object, friction=options.object_friction)
    fixed = [shape for shape in obstacles if not shape.movable]
    neighbours = [shape for shape in obstacles if shape.movable]
    _add_object(spec, fixed, scene_object, options)
    _add_neighbours(spec, neighbours, options)
    _set_contacts(spec)
    add_watch(spec, "object", [NEIGHBOUR_BODY + shape.name for shape in neighbours])
    if robot.palm_frame not in {body.name for body in spec.bodies}:
        raise ConfigError("plan robot.palm_frame", robot.palm_frame, "a link of the URDF")
    try:
        model = spec.compile()
    except ValueError as error:
        raise ConfigError(
            "plan robot.urdf", robot.urdf, f"a model MuJoCo compiles ({error})"
        ) from None
    world = _index(model, robot, root, limits, scene_object, neighbours, options)
    if pads:
        pad_contacts(world)
    return world


def _add_robot(
    spec: mujoco.MjSpec,
    robot: RobotTable,
    limits: dict[str, tuple[float, float]],
    options: PhysicsOptions,
) -> None:
    """Numerics, gravity compensation and a position actuator per joint of ``robot``.

    Raises:
        ConfigError: A joint of ``joint_names`` the URDF lacks, or an arm or hand joint
            not in ``joint_names``.
    """
    import mujoco

    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.jacobian = mujoco.mjtJacobian.mjJAC_DENSE
    spec.option.timestep = options.timestep
    # Grasping: elliptic friction cones and a high impedance ratio keep soft contacts from
    # creeping under a held load (MuJoCo's documentation for grasping).
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    spec.option.impratio = options.impratio
    for body in spec.bodies:
        if body.name != "world":
            body.gravcomp = 1.0
    joints = {joint.name: joint for joint in spec.joints}
    for name in robot.joint_names:
        if name not in joints:
            raise ConfigError("plan robot.joint_names", name, f"a joint of the URDF {list(joints)}")
    for name in (*robot.arm_joints, *robot.hand_joints):
        if name not in robot.joint_names:
            raise ConfigError("plan robot.arm_joints/hand_joints", name, "one of joint_names")
    arm_set = set(robot.arm_joints)
    for name in robot.joint_names:
        joint = joints[name]
        # URDF <dynamics> are dropped: the servo's gains stand for the drive (the Allegro
        # URDF's joint friction would hold every finger still).
        joint.damping, joint.frictionloss = [0.0, 0.0, 0.0], 0.0
        prismatic = joint.type == mujoco.mjtJoint.mjJNT_SLIDE
        velocity, effort = limits.get(name, (math.inf, math.inf))
        if name in arm_set:
            joint.armature = options.arm_armature
            kp, kv = options.arm_kp, options.arm_kv
            force = effort if math.isfinite(effort) else options.arm_force_limit
        else:
            joint.armature = options.hand_armature
            kp, kv = (
                (options.finger_kp, options.finger_kv)
                if prismatic
                else (options.hand_kp, options.hand_kv)
            )
            force = options.squeeze_force if prismatic else options.squeeze_torque
        _add_servo(spec, name, kp, kv, force)


def _add_servo(spec: mujoco.MjSpec, joint: str, kp: float, kv: float, force: float) -> None:
    """A position actuator on ``joint``: ``kp (target - q) - kv qdot`` within ``force``."""
    import mujoco

    actuator = spec.add_actuator(name=joint, target=joint)
    actuator.trntype = mujoco.mjtTrn.mjTRN_JOINT
    actuator.gaintype = mujoco.mjtGain.mjGAIN_FIXED
    actuator.biastype = mujoco.mjtBias.mjBIAS_AFFINE
    actuator.gainprm[0] = kp
    actuator.biasprm[:3] = [0.0, -kp, -kv]
    actuator.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
    actuator.forcerange = [-force, force]


def _add_object(
    spec: mujoco.MjSpec, fixed: list[Shape], scene_object: Shape, options: PhysicsOptions
) -> None:
    """The fixed obstacles (static geoms) and the object (a free body) with its contact
    parameters."""
    # condim 4: the object resists spinning about a contact normal (a pinched can);
    # priority 1: its friction and contact softness are those of every contact it makes
    # (MuJoCo would otherwise take the larger friction, 1.0 for the robot's and the table's).
    add_scene(spec, fixed, scene_object, free_object=True, **_stiff(options), condim=4)


def _add_neighbours(spec: mujoco.MjSpec, neighbours: list[Shape], options: PhysicsOptions) -> None:
    """Every movable obstacle a free body (``neighbour/<name>``) with its mass and
    friction, and the object's contact softness (a finger does not sink into it)."""
    for shape in neighbours:
        add_free_body(spec, shape, NEIGHBOUR_BODY + shape.name, **_stiff(options))


def _stiff(options: PhysicsOptions) -> dict[str, Any]:
    """Geom attributes of a free body: its own friction and softness in its contacts."""
    return {
        "priority": 1,
        "solref": [options.contact_timeconst, 1.0],
        "solimp": list(options.contact_solimp),
    }


def _set_contacts(spec: mujoco.MjSpec) -> None:
    """Robot geoms collide with the scene, not with each other; scene geoms (static, the
    object, the neighbours) with everything."""
    for geom in spec.geoms:
        scene = geom.parent.name in ("world", "object") or geom.parent.name.startswith(
            NEIGHBOUR_BODY
        )
        geom.contype, geom.conaffinity = (1, 1) if scene else (1, 0)


def _index(
    model: Any,
    robot: RobotTable,
    root: ET.Element,
    limits: dict[str, tuple[float, float]],
    scene_object: Shape,
    neighbours: list[Shape],
    options: PhysicsOptions,
) -> World:
    """The :class:`World` of a compiled model: the indices a rollout reads."""
    import mujoco

    names = list(robot.joint_names)
    jid = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n) for n in names]
    index = {n: i for i, n in enumerate(names)}
    object_joint = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "object")
    object_body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "object")
    neighbour_body = np.array(
        [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, NEIGHBOUR_BODY + s.name)
         for s in neighbours],
        dtype=np.intp,
    )  # fmt: skip
    kinds, links = _geom_kinds(model, object_body, set(neighbour_body.tolist()))
    mimic = [
        (index[m.joint], index[m.leader], m.multiplier, m.offset)
        for m in urdf_mimic(root)
        if m.joint in index and m.leader in index
    ]
    limited = model.jnt_limited[jid].astype(bool)
    ranges = model.jnt_range[jid]
    velocity = [limits.get(n, (math.inf, 0.0))[0] for n in names]
    return World(
        model=model,
        joint_names=names,
        qpos=model.jnt_qposadr[jid].astype(np.intp),
        dof=model.jnt_dofadr[jid].astype(np.intp),
        actuator=np.array(
            [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, n) for n in names],
            dtype=np.intp,
        ),
        arm=np.array([index[n] for n in robot.arm_joints], dtype=np.intp),
        hand=np.array([index[n] for n in robot.hand_joints], dtype=np.intp),
        prismatic=model.jnt_type[jid] == mujoco.mjtJoint.mjJNT_SLIDE,
        velocity_limit=np.array(
            [v if math.isfinite(v) else options.velocity_limit for v in velocity]
        ),
        lower=np.where(limited, ranges[:, 0], -np.inf),
        upper=np.where(limited, ranges[:, 1], np.inf),
        palm_body=mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, robot.palm_frame),
        object_body=object_body,
        object_qpos=int(model.jnt_qposadr[object_joint]),
        object_dof=int(model.jnt_dofadr[object_joint]),
        object_geom=int(np.flatnonzero(kinds == OBJECT)[0]),
        geom_kind=kinds,
        geom_link=links,
        mimic=mimic,
        object_shape=scene_object,
        neighbours=list(neighbours),
        neighbour_body=neighbour_body,
        neighbour_qpos=model.jnt_qposadr[model.body_jntadr[neighbour_body]].astype(np.intp),
        neighbour_dof=model.jnt_dofadr[model.body_jntadr[neighbour_body]].astype(np.intp),
        neighbour_start=np.array(
            [model.qpos0[a : a + 7] for a in model.jnt_qposadr[model.body_jntadr[neighbour_body]]]
        ).reshape(-1, 7),
        watch=watch_of(model),
    )


def _geom_kinds(
    model: Any, object_body: int, neighbour_bodies: set[int]
) -> tuple[np.ndarray, list[str]]:
    """Per geom its class (:data:`ROBOT`, ...) and its link's or shape's name."""
    kinds = np.empty(model.ngeom, dtype=np.intp)
    links = []
    for g in range(model.ngeom):
        body = int(model.geom_bodyid[g])
        if body == 0:
            kinds[g], name = OBSTACLE, model.geom(g).name
        elif body == object_body:
            kinds[g], name = OBJECT, model.geom(g).name
        elif body in neighbour_bodies:
            kinds[g], name = NEIGHBOUR, model.geom(g).name
        else:
            kinds[g] = ROBOT if model.body_weldid[body] != 0 else FIXED_ROBOT
            name = model.body(body).name
        links.append(name)
    return kinds, links
