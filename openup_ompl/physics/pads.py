"""Contact pads in the physics world (a robot file's ``[physics] pads``): their geoms, and
the contact bits that let the object and the neighbours meet the pads instead of the
URDF geometry they replace."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from openup_ompl.exceptions import ConfigError
from openup_ompl.physics.options import PhysicsOptions
from openup_ompl.physics.shapes import mujoco_quat

if TYPE_CHECKING:
    import mujoco

    from openup_ompl.physics.world import World
    from openup_ompl.robot_file import PadSpec

__all__ = ["PAD", "add_pads", "pad_contacts"]

#: Geom name prefix of a contact pad (``"pad:<link>:<index>"``).
PAD = "pad:"


def add_pads(spec: mujoco.MjSpec, pads: tuple[PadSpec, ...], options: PhysicsOptions) -> None:
    """Each pad a massless geom ``pad:<link>:<i>`` of its link's body, with its own
    friction and softness where it gives them (then it outranks the object's priority).

    Args:
        spec: The MuJoCo spec of the robot, changed in place.
        pads: The robot file's pads (poses in their link's frame [m]).
        options: The physics settings (the timestep [s] bounds a pad's softness).

    Raises:
        ConfigError: A pad on a link the URDF lacks.
    """

    bodies = {body.name: body for body in spec.bodies}
    for i, pad in enumerate(pads):
        if pad.link not in bodies:
            raise ConfigError(f"robot physics.pads[{i}].link", pad.link, "a link of the URDF")
        kind, size = _pad_geom(pad)
        extra: dict[str, Any] = {}
        if pad.friction is not None:
            extra["friction"] = [pad.friction, 0.005, 0.0001]
        if pad.timeconst is not None:
            extra["solref"] = [max(pad.timeconst, 2 * options.timestep), 1.0]
        if pad.solimp is not None:
            extra["solimp"] = [*pad.solimp, *(0.5, 2.0)[len(pad.solimp) - 3 :]]
        if extra:
            extra["priority"] = 2
        bodies[pad.link].add_geom(
            name=f"{PAD}{pad.link}:{i}", type=kind, size=size, mass=0.0,
            pos=pad.pose[:3].tolist(), quat=mujoco_quat(pad.pose).tolist(), **extra,
        )  # fmt: skip


def _pad_geom(pad: PadSpec) -> tuple[Any, list[float]]:
    """MuJoCo's geom type and size (half sizes, half length) of a pad."""
    import mujoco

    if pad.shape == "box":
        assert pad.size is not None
        return mujoco.mjtGeom.mjGEOM_BOX, (pad.size / 2).tolist()
    assert pad.radius is not None
    if pad.shape == "sphere":
        return mujoco.mjtGeom.mjGEOM_SPHERE, [pad.radius, 0.0, 0.0]
    assert pad.length is not None
    return mujoco.mjtGeom.mjGEOM_CAPSULE, [pad.radius, pad.length / 2, 0.0]


def pad_contacts(world: World) -> None:
    """Contact bits once pads exist (MuJoCo collides two geoms when ``contype`` of one
    meets ``conaffinity`` of the other): fixed obstacles (1, 1); the object and the
    neighbours (5, 6); robot geoms (3, 0); a pad (2, 0): the object and neighbours only;
    a URDF geom of a pad's link that contains the pad's centre (1, 0): obstacles only.
    Robot geoms never meet each other; every pair that met without pads still meets.

    Args:
        world: The physics world, its model's contact bits changed in place.
    """
    from openup_ompl.physics.world import FIXED_ROBOT, NEIGHBOUR, OBJECT, ROBOT

    model, kinds = world.model, world.geom_kind
    pads = [g for g in range(model.ngeom) if model.geom(g).name.startswith(PAD)]
    scene = np.isin(kinds, (OBJECT, NEIGHBOUR))
    model.geom_contype[scene], model.geom_conaffinity[scene] = 5, 6
    robot = np.isin(kinds, (ROBOT, FIXED_ROBOT))
    model.geom_contype[robot], model.geom_conaffinity[robot] = 3, 0
    for p in pads:
        model.geom_contype[p] = 2
        for g in np.flatnonzero(model.geom_bodyid == model.geom_bodyid[p]):
            if g not in pads and _contains(model, int(g), model.geom_pos[p]):
                model.geom_contype[g] = 1


def _contains(model: Any, geom: int, point: np.ndarray) -> bool:
    """Whether ``point`` (body frame) lies in the bounding box of ``geom``."""
    import mujoco

    rotation = np.zeros(9)
    mujoco.mju_quat2Mat(rotation, model.geom_quat[geom])
    local = rotation.reshape(3, 3).T @ (point - model.geom_pos[geom])
    centre, half = model.geom_aabb[geom][:3], model.geom_aabb[geom][3:]
    return bool(np.all(np.abs(local - centre) <= half + 1e-9))
