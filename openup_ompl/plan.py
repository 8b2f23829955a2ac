"""Plans: the result of a solve, and the plan file (README, Files: Plan): its writer
(:meth:`Plan.save`) and its reader (:class:`PlanFile`), side by side."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from openup_ompl._io import read_json, write_atomic
from openup_ompl._model import frame_id
from openup_ompl.exceptions import ConfigError, JointNotFound
from openup_ompl.hand_law import HandLaw
from openup_ompl.scene import Problem, Shape

PLAN_FORMAT = "openup-plan/1"


@dataclass(eq=False)
class Plan:
    """A collision-free reach-to-grasp plan.

    Attributes:
        path: ``(N, nq)`` full configurations (arm and hand) in Pinocchio's ``q`` order,
            no robot point moving more than the checker's resolution between consecutive
            rows (the straight arm motion between them checked exactly),
            the hand set by the law at every row. Row 0 is the start; the last row puts the
            palm on the grasp pose.
        waypoints: ``(M, dof)`` arm configurations the planner returned (after
            simplification, if any); ``path`` interpolates them.
        status: OMPL's planner status, as text.
        planner: Planner name.
        seed: Seed of the run.
        solve_time_s: Planning time [s] (simplification excluded).
        problem: The problem solved.
        law: The hand law the plan follows.
        start_palm_distance: Palm-to-grasp distance at the start [m] (Algorithm 1's
            denominator).
        stats: Counters of the run (validity checks, IK calls, ...).
    """

    path: np.ndarray
    waypoints: np.ndarray
    status: str
    planner: str
    seed: int | None
    solve_time_s: float
    problem: Problem
    law: HandLaw
    start_palm_distance: float
    stats: dict[str, Any] = field(default_factory=dict)

    @property
    def arm_path(self) -> np.ndarray:
        """``(N, dof)`` arm joint values of :attr:`path`."""
        return self.path[:, self.problem.robot.arm_idx]

    @property
    def hand_path(self) -> np.ndarray:
        """``(N, hand dof)`` hand joint values of :attr:`path`."""
        return self.path[:, self.problem.robot.hand_idx]

    def to_dict(self) -> dict[str, Any]:
        """The plan file's contents (README, Files: Plan)."""
        robot = self.problem.robot
        spec = robot.spec
        scene_object = self.problem.object
        return {
            "format": PLAN_FORMAT,
            "status": self.status,
            "planner": self.planner,
            "seed": self.seed,
            "solve_time_s": self.solve_time_s,
            "robot": {
                "name": spec.name,
                "urdf": str(robot.urdf),
                "srdf": None if robot.srdf is None else str(robot.srdf),
                "package_dirs": list(robot.package_dirs),
                "palm_frame": spec.palm_frame,
                "joint_names": robot.joint_names,
                "arm_joints": list(spec.arm_joints),
                "hand_joints": list(robot.hand_joints),
            },
            "scene": {
                "object": None if scene_object is None else scene_object.raw,
                "obstacles": [shape.raw for shape in self.problem.obstacles],
            },
            "start": self.problem.start.tolist(),
            "grasp_pose": self.problem.grasp_pose.tolist(),
            "hand_law": {**self.law.to_dict(), "start_palm_distance": self.start_palm_distance},
            "waypoints": self.waypoints.tolist(),
            "stats": self.stats,
            "path": self.path.tolist(),
        }

    def save(self, path: str | Path) -> Path:
        """Write the plan file (JSON, README, Files: Plan), atomically; returns its path."""
        path = Path(path)
        if not np.all(np.isfinite(self.path)):
            raise ConfigError("plan path", "non-finite values", "a finite path")
        return write_atomic(path, _plan_json(self.to_dict()))


def _plan_json(data: dict[str, Any]) -> str:
    """The plan file's text: indented, with one line per row of ``path`` and ``waypoints``
    (written by the C encoder: the indented encoder is pure Python and took 0.1 s for a
    plan of 2400 rows, a third of ``openup-ompl plan``'s own work)."""
    rows = {key: data[key] for key in ("path", "waypoints")}
    marks = {key: f"@@{key}@@" for key in rows}
    text = json.dumps({**data, **marks}, indent=1, allow_nan=False)
    for key, value in rows.items():
        # Rows of numbers only: "], [" occurs between rows and nowhere else.
        lines = json.dumps(value, allow_nan=False)[1:-1].replace("], [", "],\n  [")
        text = text.replace(json.dumps(marks[key]), f"[\n  {lines}\n ]", 1)
    return text


def read_plan(path: str | Path) -> dict[str, Any]:
    """Read a plan file and check its format and path shape."""
    path = Path(path)
    data = read_json(path, PLAN_FORMAT, "plan file")
    rows = data.get("path")
    names = data.get("robot", {}).get("joint_names", [])
    if not (
        isinstance(rows, list)
        and rows
        and all(isinstance(r, list) and len(r) == len(names) for r in rows)
    ):
        raise ConfigError(f"{path.name}: path", "malformed", f"rows of {len(names)} joint values")
    if not all(math.isfinite(x) for row in rows for x in row):
        raise ConfigError(f"{path.name}: path", "non-finite values", "finite joint values")
    return data


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


def _urdf_model(urdf: str) -> pin.Model:
    if not Path(urdf).is_file():
        raise ConfigError("robot.urdf", urdf, "an existing URDF file")
    try:
        return pin.buildModelFromUrdf(urdf)
    except (RuntimeError, ValueError) as error:
        raise ConfigError("robot.urdf", urdf, f"a loadable URDF ({error})") from None


@dataclass(frozen=True, eq=False)
class PlanFile:
    """A plan as a plan file holds it, typed and checked: robot, law, shapes, path.

    Built from a plan file alone and the URDF it names (:meth:`read`), so that a plan
    can be replayed or drawn without its scene or robot TOML; or from a :class:`Plan` in
    memory (:meth:`from_plan`), with the same kinematic model.

    Attributes:
        name: A short name for titles (the plan file's stem).
        planner: The planner's name.
        seed: Seed of the run, or ``None``.
        status: OMPL's planner status, as text.
        urdf: The URDF of the whole robot.
        package_dirs: Directories resolving its ``package://`` mesh URIs.
        model: Pinocchio model built from :attr:`urdf`.
        hand_joints: Hand joint names, in the law's order.
        hand_idx: Indices in ``q`` of the hand joints, in the law's order.
        palm_frame_id: Pinocchio frame index of the palm frame.
        law: The hand law the plan followed (limits from :attr:`model`).
        grasp_pose: Palm frame target ``[x, y, z, qx, qy, qz, qw]`` (world frame).
        path: ``(N, nq)`` full configurations.
        obstacles: The scene's obstacles.
        object: The object to grasp, or ``None``.
    """

    name: str
    planner: str
    seed: int | None
    status: str
    urdf: Path
    package_dirs: tuple[str, ...]
    model: pin.Model
    hand_joints: tuple[str, ...]
    hand_idx: np.ndarray
    palm_frame_id: int
    law: HandLaw
    grasp_pose: np.ndarray
    path: np.ndarray
    obstacles: tuple[Shape, ...]
    object: Shape | None

    @classmethod
    def read(cls, path: str | Path) -> PlanFile:
        """Read and check a plan file (:func:`read_plan`) and load its robot's model.

        Raises:
            ConfigError: The file is not a readable plan, a key is missing or holds a bad
                value, or its URDF cannot be loaded.
            JointNotFound, FrameNotFound: The plan names a joint or frame its URDF lacks.
        """
        path = Path(path)
        return cls.from_dict(read_plan(path), path.stem)

    @classmethod
    def from_dict(cls, data: dict[str, Any], name: str = "plan") -> PlanFile:
        """Check a plan file's contents (as :meth:`Plan.to_dict` gives them) and load
        its robot's model (see :meth:`read`)."""
        robot = _key(data, "robot")
        urdf = str(_key(robot, "urdf", "robot"))
        model = _urdf_model(urdf)
        names = [model.names[i] for i in range(1, model.njoints) if model.joints[i].nq > 0]
        if list(_key(robot, "joint_names", "robot")) != names:
            raise ConfigError("robot.joint_names", robot["joint_names"], f"{names} (the URDF's)")
        hand_joints = tuple(_key(robot, "hand_joints", "robot"))
        for joint in hand_joints:
            if not model.existJointName(joint):
                raise JointNotFound(joint, names)
        hand_idx = np.array([model.joints[model.getJointId(n)].idx_q for n in hand_joints])
        palm_frame_id = frame_id(model, str(_key(robot, "palm_frame", "robot")))
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
        scene = _key(data, "scene")
        if not isinstance(scene, dict):
            raise ConfigError("scene", scene, "a table with the object and obstacles")
        obstacles = tuple(
            Shape.from_table(table, f"scene.obstacles[{i}]")
            for i, table in enumerate(scene.get("obstacles") or [])
        )
        raw_object = scene.get("object")
        return cls(
            name=name,
            planner=str(data.get("planner", "plan")),
            seed=data.get("seed"),
            status=str(data.get("status", "")),
            urdf=Path(urdf),
            package_dirs=tuple(str(p) for p in robot.get("package_dirs") or []),
            model=model,
            hand_joints=hand_joints,
            hand_idx=hand_idx.astype(np.intp),
            palm_frame_id=palm_frame_id,
            law=law,
            grasp_pose=_numbers(_key(data, "grasp_pose"), "grasp_pose", (7,)),
            path=_numbers(_key(data, "path"), "path", (-1, model.nq)),
            obstacles=obstacles,
            object=None
            if not raw_object
            else Shape.from_table(raw_object, "scene.object", is_object=True),
        )

    @classmethod
    def from_plan(cls, plan: Plan, name: str = "plan") -> PlanFile:
        """What the plan file of ``plan`` would hold, without writing and re-reading it:
        its law, shapes and path as they are; the model built from the robot's URDF."""
        robot = plan.problem.robot
        model = _urdf_model(str(robot.urdf))
        hand_idx = np.array(
            [model.joints[model.getJointId(n)].idx_q for n in robot.hand_joints], dtype=np.intp
        )
        return cls(
            name=name,
            planner=plan.planner,
            seed=plan.seed,
            status=plan.status,
            urdf=Path(str(robot.urdf)),
            package_dirs=tuple(str(p) for p in robot.package_dirs),
            model=model,
            hand_joints=tuple(robot.hand_joints),
            hand_idx=hand_idx,
            palm_frame_id=frame_id(model, robot.spec.palm_frame),
            law=plan.law,
            grasp_pose=plan.problem.grasp_pose,
            path=plan.path,
            obstacles=tuple(plan.problem.obstacles),
            object=plan.problem.object,
        )

    @property
    def grasp(self) -> pin.SE3:
        """Grasp pose of the palm frame as a Pinocchio ``SE3`` (world frame)."""
        return pin.XYZQUATToSE3(self.grasp_pose)
