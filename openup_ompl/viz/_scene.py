"""A plan file loaded for display: robot kinematics and geometry, scene shapes, the law.

Built from the plan file alone (CONTRACT §4) and the URDF and meshes it names, so that a
plan can be shown without its scene or robot TOML. Needs only pinocchio, coal and numpy.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from openup_ompl._model import prismatic_joints
from openup_ompl.exceptions import ConfigError, FrameNotFound, JointNotFound
from openup_ompl.hand_law import GoalDistance, HandLaw
from openup_ompl.plan import read_plan
from openup_ompl.scene import Shape


def _key(table: Any, key: str, where: str = "") -> Any:
    """``table[key]``, or a ConfigError naming the missing ``where.key``."""
    name = f"{where}.{key}" if where else key
    if not isinstance(table, dict) or key not in table:
        raise ConfigError(name, None, f"a plan file with {name}")
    return table[key]


def _numbers(value: Any, where: str, shape: tuple[int, ...]) -> np.ndarray:
    """``value`` as a finite float array of ``shape`` (-1: any length), or a ConfigError."""
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        array = np.zeros(0)
    fits = array.ndim == len(shape) and all(
        n in (-1, m) for n, m in zip(shape, array.shape, strict=True)
    )
    if not (fits and array.size and np.all(np.isfinite(array))):
        expected = "[x, y, z, qx, qy, qz, qw]" if shape == (7,) else f"rows of {shape[-1]} values"
        shown = value if isinstance(value, list) and len(value) <= 7 else "malformed"
        raise ConfigError(where, shown, expected)
    return array


@dataclass(eq=False)
class PlanScene:
    """Everything needed to draw a plan.

    Attributes:
        data: The plan file's contents.
        name: A short name for titles (the plan file's stem).
        model: Pinocchio model of the robot (the plan's URDF).
        path: ``(N, nq)`` full configurations of the plan.
        hand_idx: Indices in ``q`` of the hand joints, in the law's order.
        hand_joints: Hand joint names, in the law's order.
        prismatic: Per hand joint, whether it is prismatic [m] (else revolute [rad]).
        palm_frame_id: Pinocchio frame index of the palm frame.
        law: The hand law the plan followed.
        grasp: Grasp pose of the palm frame (world frame).
        palm: ``(N, 3)`` palm frame origin at every row [m] (world frame).
        distances: Normalised palm-to-grasp distance ``d`` at every row (Algorithm 1).
        progress: Palm path length travelled at every row, normalised to [0, 1].
        shapes: The scene's obstacles, then the object (if any).
        object_name: Name of the object to grasp, or ``None``.
    """

    data: dict[str, Any]
    name: str
    model: pin.Model
    path: np.ndarray
    hand_idx: np.ndarray
    hand_joints: list[str]
    prismatic: np.ndarray
    palm_frame_id: int
    law: HandLaw
    grasp: pin.SE3
    palm: np.ndarray
    distances: np.ndarray
    progress: np.ndarray
    shapes: list[Shape]
    object_name: str | None

    @classmethod
    def from_file(cls, path: str | Path) -> PlanScene:
        """Read and check a plan file (:func:`openup_ompl.read_plan`) and load its robot.

        Raises:
            ConfigError: The file is not a readable plan, a key is missing or holds a bad
                value, or its URDF or meshes cannot be loaded.
            JointNotFound, FrameNotFound: The plan names a joint or frame its URDF lacks.
        """
        path = Path(path)
        return cls.from_dict(read_plan(path), path.stem)

    @classmethod
    def from_dict(cls, data: dict[str, Any], name: str = "plan") -> PlanScene:
        """Load a plan's contents (as :meth:`openup_ompl.Plan.to_dict` gives them)."""
        robot = _key(data, "robot")
        urdf = str(_key(robot, "urdf", "robot"))
        if not Path(urdf).is_file():
            raise ConfigError("robot.urdf", urdf, "an existing URDF file")
        try:
            model = pin.buildModelFromUrdf(urdf)
        except (RuntimeError, ValueError) as error:
            raise ConfigError("robot.urdf", urdf, f"a loadable URDF ({error})") from None
        names = [model.names[i] for i in range(1, model.njoints) if model.joints[i].nq > 0]
        if list(_key(robot, "joint_names", "robot")) != names:
            raise ConfigError("robot.joint_names", robot["joint_names"], f"{names} (the URDF's)")
        hand_joints = list(_key(robot, "hand_joints", "robot"))
        for joint in hand_joints:
            if not model.existJointName(joint):
                raise JointNotFound(joint, names)
        joints = [model.joints[model.getJointId(n)] for n in hand_joints]
        hand_idx = np.array([j.idx_q for j in joints], dtype=np.intp)
        prismatic = prismatic_joints(model, hand_joints)
        palm_frame = str(_key(robot, "palm_frame", "robot"))
        if not model.existFrame(palm_frame):
            raise FrameNotFound(palm_frame, [f.name for f in model.frames])

        table = _key(data, "hand_law")
        if not isinstance(table, dict):
            raise ConfigError("hand_law", table, "a table with c, b, w, u, mga")
        law = HandLaw.from_table(
            table,
            model.lowerPositionLimit[hand_idx],
            model.upperPositionLimit[hand_idx],
            "hand_law",
            ignore=("start_palm_distance",),
        )
        grasp_pose = _numbers(_key(data, "grasp_pose"), "grasp_pose", (7,))
        grasp = pin.XYZQUATToSE3(grasp_pose)
        path = _numbers(_key(data, "path"), "path", (-1, model.nq))
        try:
            palm_frame_id = model.getFrameId(palm_frame)
        except ValueError:  # a joint and a link of that name: the link's frame
            palm_frame_id = model.getFrameId(palm_frame, pin.FrameType.BODY)
        kinematics = model.createData()
        placements = []
        for q in path:
            pin.framesForwardKinematics(model, kinematics, q)
            placements.append(kinematics.oMf[palm_frame_id].copy())
        goal = GoalDistance(grasp, placements[0], law.distance, law.rotation_weight)
        palm = np.array([p.translation for p in placements])
        travel = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(palm, axis=0), axis=1))])

        scene = _key(data, "scene")
        if not isinstance(scene, dict):
            raise ConfigError("scene", scene, "a table with the object and obstacles")
        shapes = [
            Shape.from_table(table, f"scene.obstacles[{i}]")
            for i, table in enumerate(scene.get("obstacles") or [])
        ]
        object_name = None
        if scene.get("object"):
            shapes.append(Shape.from_table(scene["object"], "scene.object"))
            object_name = shapes[-1].name
        return cls(
            data=data,
            name=name,
            model=model,
            path=path,
            hand_idx=hand_idx,
            hand_joints=hand_joints,
            prismatic=prismatic,
            palm_frame_id=palm_frame_id,
            law=law,
            grasp=grasp,
            palm=palm,
            distances=np.array([goal(p) for p in placements]),
            progress=travel / max(float(travel[-1]), 1e-12),
            shapes=shapes,
            object_name=object_name,
        )

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
        robot = self.data["robot"]
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                return pin.buildGeomFromUrdf(
                    self.model,
                    robot["urdf"],
                    kind,
                    package_dirs=[str(p) for p in robot.get("package_dirs") or []],
                )
        except (RuntimeError, ValueError) as error:
            raise ConfigError(
                "robot.package_dirs", robot.get("package_dirs"), f"the URDF's meshes ({error})"
            ) from None

    def hand_geometry(self, geometry: pin.GeometryModel) -> np.ndarray:
        """Per geometry object, whether it moves with a hand joint (a finger)."""
        hand_ids = {self.model.getJointId(n) for n in self.hand_joints}
        return np.array(
            [
                bool(hand_ids.intersection(self.model.supports[g.parentJoint]))
                for g in geometry.geometryObjects
            ],
            dtype=bool,
        )

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
