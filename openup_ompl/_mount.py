"""A hand mounted on an arm: two robot descriptions composed into one Pinocchio model
(a robot file's ``[mount]``)."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import pinocchio as pin

from openup_ompl._model import frame_id
from openup_ompl.exceptions import FrameNotFound
from openup_ompl.robot_file import MountSpec, RobotSpec
from openup_ompl.urdf import (
    _build,
    _convex_hulls,
    _merged_srdf,
    _merged_urdf,
    remove_srdf_pairs,
    urdf_tree,
)

__all__ = ["mount_hand"]


def mount_hand(
    spec: RobotSpec,
    mount: MountSpec,
    model: pin.Model,
    collision: pin.GeometryModel,
    urdf_root: ET.Element,
    package_dirs: list[str],
) -> tuple[pin.Model, pin.GeometryModel, Path, ET.Element, Path]:
    """Fix the hand of ``mount`` to the arm's ``mount.frame`` at ``mount.pose``
    (``pinocchio.appendModel``), with collision pairs between every two geometries on
    different joints minus the arm's and hand's SRDF pairs, the pair (arm link holding
    the frame, hand root link) and ``mount.disable_collisions``.

    Args:
        spec: The robot file.
        mount: Its ``[mount]``.
        model: The arm's model.
        collision: The arm's collision geometry.
        urdf_root: The arm's parsed URDF tree.
        package_dirs: Where meshes are looked up; the hand's URDF folders are added.

    Returns:
        The composed model and geometry, the merged URDF's path and parsed tree, and
        the merged SRDF's path.

    Raises:
        FrameNotFound: ``mount.frame`` or a name of ``mount.disable_collisions`` is no
            frame of the composed model.
    """
    for extra in (mount.urdf.parent, mount.urdf.parent.parent):
        if str(extra) not in package_dirs:
            package_dirs.append(str(extra))
    if not any(f.name == mount.frame for f in model.frames):
        raise FrameNotFound(mount.frame, [f.name for f in model.frames])
    urdf, hand_urdf, hand_srdf = _merged_urdf(spec, mount, model, package_dirs, urdf_root)
    urdf_root = urdf_tree(urdf, f"{spec.path.name}: merged urdf")
    hand_model, hand_collision, _ = _build(hand_urdf, package_dirs, f"{spec.path.name}: mount.urdf")
    hand_root = hand_model.frames[1].name
    mount_id = frame_id(model, mount.frame)
    body = model.frames[mount_id]
    while body.type != pin.FrameType.BODY and body.parentFrame != 0:
        body = model.frames[body.parentFrame]
    model, collision = pin.appendModel(
        model, hand_model, collision, hand_collision, mount_id, pin.XYZQUATToSE3(mount.pose)
    )
    collision.removeAllCollisionPairs()
    if spec.convex:
        _convex_hulls(model, collision, spec.path.name)
    collision.addAllCollisionPairs()
    frames = {f.name for f in model.frames}
    for pair in mount.disable_collisions:
        for name in pair:
            if name not in frames:
                raise FrameNotFound(name, sorted(frames))
    srdf = _merged_srdf(spec, mount, hand_srdf, [(body.name, hand_root), *mount.disable_collisions])
    remove_srdf_pairs(model, collision, srdf, f"{spec.path.name}: merged srdf")
    return model, collision, urdf, urdf_root, srdf
