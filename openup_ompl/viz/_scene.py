"""A plan prepared for display: what drawing needs beyond the plan file's contents.

The file is read by :class:`openup_ompl.plan.PlanFile` (beside its writer); this adds the
palm track, the normalised distance along the plan, the robot's meshes. Needs only
pinocchio, coal and numpy.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from openup_ompl._model import moved_by, prismatic_joints
from openup_ompl.exceptions import ConfigError
from openup_ompl.hand_law import HandLaw, NormalizedDistance
from openup_ompl.plan import Plan, PlanFile
from openup_ompl.scene import Shape


@dataclass(eq=False)
class PlanScene:
    """Everything needed to draw a plan.

    Attributes:
        plan: The plan as its file holds it (robot model, law, shapes, path).
        name: A short name for titles (the plan file's stem).
        prismatic: Per hand joint, whether it is prismatic [m] (else revolute [rad]).
        palm: ``(N, 3)`` palm frame origin at every row [m] (world frame).
        distances: Normalised palm-to-grasp distance ``d`` at every row (Algorithm 1).
        progress: Palm path length travelled at every row, normalised to [0, 1].
        shapes: The scene's obstacles, then the object (if any).
        object_name: Name of the object to grasp, or ``None``.
    """

    plan: PlanFile
    name: str
    prismatic: np.ndarray
    palm: np.ndarray
    distances: np.ndarray
    progress: np.ndarray
    shapes: list[Shape]
    object_name: str | None

    @classmethod
    def from_file(cls, path: str | Path) -> PlanScene:
        """Read a plan file; raises what :meth:`openup_ompl.plan.PlanFile.read` raises."""
        return cls.from_plan_file(PlanFile.read(path))

    @classmethod
    def from_dict(cls, data: dict[str, Any], name: str = "plan") -> PlanScene:
        """Load a plan's contents (as :meth:`openup_ompl.Plan.to_dict` gives them)."""
        return cls.from_plan_file(PlanFile.from_dict(data, name))

    @classmethod
    def from_plan(cls, plan: Plan, name: str = "plan") -> PlanScene:
        """Draw a plan in memory (no plan file written or read)."""
        return cls.from_plan_file(PlanFile.from_plan(plan, name))

    @classmethod
    def from_plan_file(cls, plan: PlanFile) -> PlanScene:
        """What drawing ``plan`` needs beyond the file: palm track, ``d``, progress."""
        model = plan.model
        kinematics = model.createData()
        placements = []
        for q in plan.path:
            pin.framesForwardKinematics(model, kinematics, q)
            placements.append(kinematics.oMf[plan.palm_frame_id].copy())
        law = plan.law
        goal = NormalizedDistance(plan.grasp, placements[0], law.distance, law.rotation_weight)
        palm = np.array([p.translation for p in placements])
        travel = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(palm, axis=0), axis=1))])
        shapes = [*plan.obstacles, *([plan.object] if plan.object is not None else [])]
        return cls(
            plan=plan,
            name=plan.name,
            prismatic=prismatic_joints(model, plan.hand_joints),
            palm=palm,
            distances=np.array([goal(p) for p in placements]),
            progress=travel / max(float(travel[-1]), 1e-12),
            shapes=shapes,
            object_name=None if plan.object is None else plan.object.name,
        )

    @property
    def model(self) -> pin.Model:
        """Pinocchio model of the robot (the plan's URDF)."""
        return self.plan.model

    @property
    def path(self) -> np.ndarray:
        """``(N, nq)`` full configurations of the plan."""
        return self.plan.path

    @property
    def hand_idx(self) -> np.ndarray:
        """Indices in ``q`` of the hand joints, in the law's order."""
        return self.plan.hand_idx

    @property
    def hand_joints(self) -> list[str]:
        """Hand joint names, in the law's order."""
        return list(self.plan.hand_joints)

    @property
    def palm_frame_id(self) -> int:
        """Pinocchio frame index of the palm frame."""
        return self.plan.palm_frame_id

    @property
    def law(self) -> HandLaw:
        """The hand law the plan followed."""
        return self.plan.law

    @property
    def grasp(self) -> pin.SE3:
        """Grasp pose of the palm frame (world frame)."""
        return self.plan.grasp

    @property
    def hand_path(self) -> np.ndarray:
        """``(N, hand dof)`` hand joint values along the plan."""
        return self.path[:, self.hand_idx]

    @property
    def mga_row(self) -> int | None:
        """The first row at which ``d`` is at most ``mga`` (the maximum grip aperture)."""
        rows = np.flatnonzero(self.distances <= self.law.mga)
        return int(rows[0]) if rows.size else None

    def opening(self, hand: np.ndarray) -> np.ndarray:
        """How far each hand configuration is from ``c`` towards ``w``: 0 at ``c``, 1 at
        ``w`` (mean over the joints where ``w`` differs from ``c``)."""
        span = self.law.w - self.law.c
        moving = np.abs(span) > 1e-12
        if not np.any(moving):
            return np.zeros(np.atleast_2d(hand).shape[0])
        ratio = (np.atleast_2d(hand)[:, moving] - self.law.c[moving]) / span[moving]
        return np.asarray(ratio.mean(axis=1))

    def hand_text(self, hand: np.ndarray) -> str:
        """Hand joint values for a label: millimetres or degrees, ``2 × 37.9 mm`` when
        equal, the joint count beyond three."""
        values = [
            f"{v * 1e3:.1f} mm" if p else f"{np.degrees(v):.0f}°"
            for v, p in zip(hand, self.prismatic, strict=True)
        ]
        if len(set(values)) == 1 and len(values) > 1:
            return f"{len(values)} × {values[0]}"
        return ", ".join(values) if len(values) <= 3 else f"{len(values)} joints"

    def geometry_model(self, kind: pin.GeometryType) -> pin.GeometryModel:
        """The robot's visual or collision geometry, meshes loaded from the plan's
        package directories.

        Raises:
            ConfigError: A mesh cannot be found or loaded.
        """
        dirs = list(self.plan.package_dirs)
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                return pin.buildGeomFromUrdf(
                    self.model, str(self.plan.urdf), kind, package_dirs=dirs
                )
        except (RuntimeError, ValueError) as error:
            raise ConfigError("robot.package_dirs", dirs, f"the URDF's meshes ({error})") from None

    def hand_geometry(self, geometry: pin.GeometryModel) -> np.ndarray:
        """Per geometry object, whether it moves with a hand joint (a finger)."""
        return moved_by(self.model, geometry, self.hand_joints)

    def view_direction(self) -> np.ndarray:
        """A unit vector from the scene towards a camera that sees the reach from the side
        and a little from the front and above (world frame)."""
        reach = self.grasp.translation - self.palm[0]
        reach[2] = 0.0
        if np.linalg.norm(reach) < 1e-6:
            reach = np.array([1.0, 0.0, 0.0])
        reach /= np.linalg.norm(reach)
        side = np.cross(np.array([0.0, 0.0, 1.0]), reach)
        direction = -0.8 * side + 0.45 * reach + np.array([0.0, 0.0, 0.5])
        return np.asarray(direction / np.linalg.norm(direction))
