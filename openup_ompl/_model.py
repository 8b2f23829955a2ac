"""Small queries on a Pinocchio model shared by the loader, the bounds and the viewer."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from openup_ompl.exceptions import FrameNotFound

#: Pinocchio's prismatic joint kinds (``JointModelPX``, ..., ``JointModelPrismaticUnaligned``).
_PRISMATIC = ("PX", "PY", "PZ", "PrismaticUnaligned")


def frame_id(model: pin.Model, name: str) -> int:
    """Index of the frame ``name``; the BODY frame when several frames share the name
    (e.g. a link and a joint both called ``gripperStator``)."""
    matches = [f for f in model.frames if f.name == name]
    if not matches:
        raise FrameNotFound(name, [f.name for f in model.frames])
    if len(matches) > 1 and any(f.type == pin.FrameType.BODY for f in matches):
        return int(model.getFrameId(name, pin.FrameType.BODY))
    return int(model.getFrameId(name, matches[0].type))


def is_prismatic(joint: pin.JointModel) -> bool:
    """Whether a joint is prismatic (its value in metres; else radians)."""
    return any(joint.shortname().endswith(kind) for kind in _PRISMATIC)


def prismatic_joints(model: pin.Model, names: Sequence[str]) -> np.ndarray:
    """Per joint name, whether it is prismatic (values in metres; else radians)."""
    return np.array([is_prismatic(model.joints[model.getJointId(n)]) for n in names], dtype=bool)


def moved_by(model: pin.Model, geometry: pin.GeometryModel, joints: Sequence[str]) -> np.ndarray:
    """Per geometry object, whether one of the named joints moves it (it lies on a link
    those joints carry): for a hand's joints, the fingers."""
    ids = {int(model.getJointId(name)) for name in joints}
    return np.array(
        [bool(ids.intersection(model.supports[g.parentJoint])) for g in geometry.geometryObjects],
        dtype=bool,
    )


def selector(indices: np.ndarray) -> slice | np.ndarray:
    """A slice equal to a run of consecutive indices (faster indexing), else the indices."""
    if indices.size and np.all(np.diff(indices) == 1):
        return slice(int(indices[0]), int(indices[-1]) + 1)
    return indices


def q_indices(model: pin.Model, joints: Sequence[str]) -> np.ndarray:
    """Indices in ``q`` of the named one-value joints, in their order."""
    return np.array([model.joints[model.getJointId(n)].idx_q for n in joints], dtype=np.intp)
