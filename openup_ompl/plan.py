"""Plans: the result of a solve, and the plan file (README, Files: Plan): its writer
(:meth:`Plan.save`) and its reader (:class:`PlanFile`), side by side."""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from openup_ompl import _toml
from openup_ompl._io import read_json, write_atomic
from openup_ompl._model import frame_id
from openup_ompl.exceptions import ConfigError, FrameNotFound
from openup_ompl.hand_law import HandLaw, palm_distance
from openup_ompl.ik import MAX_POSITION_TOLERANCE, MAX_ROTATION_TOLERANCE
from openup_ompl.scene import Problem, Shape, check_unique_names
from openup_ompl.urdf import urdf_model

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
                "file": str(spec.path),
                "urdf": str(robot.urdf),
                "srdf": None if robot.srdf is None else str(robot.srdf),
                "package_dirs": list(robot.package_dirs),
                "palm_frame": spec.palm_frame,
                "joint_names": robot.joint_names,
                "arm_joints": list(spec.arm_joints),
                "hand_joints": list(robot.hand_joints),
            },
            "scene": {
                "object": None if scene_object is None else scene_object.to_table(),
                "obstacles": [shape.to_table() for shape in self.problem.obstacles],
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
        if not isinstance(path, (str, os.PathLike)) or Path(path).is_dir():
            raise ConfigError("plan file", path, "a path to a file to write")
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
    """Read a plan file and check it whole, as :meth:`PlanFile.read` does (the one check
    of ``show`` and ``execute``); returns its contents.

    Raises:
        ConfigError: What :meth:`PlanFile.read` raises.
    """
    return PlanFile.read(path).contents


#: Slack [rad or m] a plan file's path may have beyond a joint limit (the planner's rows
#: lie within the limits; this only absorbs rounding).
LIMIT_TOLERANCE = 1e-6

#: How far [m] the palm may be from a plan's grasp pose at the path's last row: a plan
#: ends where IK put the palm (within ``IKOptions.position_tolerance``, 1e-5 m by
#: default; :class:`~openup_ompl.ik.IKOptions` refuses more than this).
GRASP_POSITION_TOLERANCE = MAX_POSITION_TOLERANCE
#: The same for the palm's rotation [rad].
GRASP_ROTATION_TOLERANCE = MAX_ROTATION_TOLERANCE


def number_rows(value: Any, where: str, width: int) -> np.ndarray:
    """``value`` (a non-empty list of rows of ``width`` finite numbers) as an
    ``(N, width)`` array.

    Raises:
        ConfigError: Not such a list, naming the first bad row or value
            (``where[i]`` or ``where[i][j]``).
    """
    if isinstance(value, np.ndarray):
        if value.dtype.kind in "fiu" and value.ndim == 2 and value.shape[1] == width:
            array = value.astype(float)
            if array.size and np.isfinite(array).all():
                return array
        value = value.tolist()  # checked below, naming the bad row or value
    if not (isinstance(value, list) and value):
        raise ConfigError(where, value, f"a non-empty list of rows of {width} numbers")
    for i, row in enumerate(value):
        if not (isinstance(row, list) and len(row) == width):
            raise ConfigError(f"{where}[{i}]", row, f"a row of {width} numbers")
        for j, x in enumerate(row):
            if type(x) not in (int, float):
                raise ConfigError(f"{where}[{i}][{j}]", x, "a number")
    array = np.array(value, dtype=float)
    bad = np.argwhere(~np.isfinite(array))
    if bad.size:
        i, j = bad[0]
        raise ConfigError(f"{where}[{i}][{j}]", float(array[i, j]), "a finite number")
    return array


def _path(value: Any, where: str, model: pin.Model) -> np.ndarray:
    """A plan's ``path``: rows of ``model.nq`` finite joint values within the joint limits
    (:data:`LIMIT_TOLERANCE`), or a ConfigError naming the row, the joint and its limits."""
    path = number_rows(value, where, model.nq)
    columns = [model.names[i] for i in range(1, model.njoints) for _ in range(model.joints[i].nq)]
    low, high = model.lowerPositionLimit, model.upperPositionLimit
    outside = np.argwhere((path < low - LIMIT_TOLERANCE) | (path > high + LIMIT_TOLERANCE))
    if outside.size:
        i, j = outside[0]
        raise ConfigError(
            f"{where}[{i}][{j}]",
            float(path[i, j]),
            f"{columns[j]} within its limits [{low[j]:.6g}, {high[j]:.6g}]",
        )
    return path


def _check_ends(
    path: np.ndarray,
    start: np.ndarray | None,
    arm_idx: np.ndarray,
    model: pin.Model,
    palm_frame_id: int,
    grasp_pose: np.ndarray,
    where: str,
) -> None:
    """A plan's path must leave from its ``start`` (when the file names one) and end with
    the palm at its grasp pose: a path edited, reversed or cut short would otherwise be
    drawn and executed as the plan for that grasp."""
    if start is not None and np.max(np.abs(path[0, arm_idx] - start)) > LIMIT_TOLERANCE:
        raise ConfigError(
            f"{where}path[0]",
            np.round(path[0, arm_idx], 6).tolist(),
            f"the arm at the plan's start {np.round(start, 6).tolist()}",
        )
    data = model.createData()
    pin.framesForwardKinematics(model, data, path[-1])
    error = data.oMf[palm_frame_id].actInv(pin.XYZQUATToSE3(grasp_pose))
    distance = float(np.linalg.norm(error.translation))
    angle = float(np.linalg.norm(pin.log3(error.rotation)))
    if distance > GRASP_POSITION_TOLERANCE or angle > GRASP_ROTATION_TOLERANCE:
        raise ConfigError(
            f"{where}path[{len(path) - 1}]",
            f"the palm {distance * 1e3:.1f} mm and {angle:.3f} rad from grasp_pose",
            f"the last row at the grasp pose (within {GRASP_POSITION_TOLERANCE * 1e3:g} mm "
            f"and {GRASP_ROTATION_TOLERANCE:g} rad)",
        )


#: How far [rad or m] a path row's hand joint may be from the hand law's value there
#: (rounding: the planner writes the law's value itself).
HAND_TOLERANCE = 1e-6
#: The least palm-to-grasp distance [m] at a plan's start: the planner refuses a start
#: closer to its grasp (:data:`~openup_ompl.validity.MIN_START_DISTANCE`), and the law's
#: normalised distance divides by it.
MIN_START_PALM_DISTANCE = MAX_POSITION_TOLERANCE


def _check_hand(
    path: np.ndarray,
    law: HandLaw,
    start_distance: float | None,
    model: pin.Model,
    hand_idx: np.ndarray,
    hand_joints: tuple[str, ...],
    palm_frame_id: int,
    grasp_pose: np.ndarray,
    where: str,
) -> None:
    """Every row's hand joints must hold what the file's law gives for that row's arm
    (as :meth:`~openup_ompl.planning.GraspPlanningSetup.densify` wrote them): a file whose
    ``hand_joints`` are reordered, or whose hand columns were edited, would otherwise be
    drawn and executed as a plan of that law.

    ``d`` at a row is the palm's distance to ``grasp_pose`` (the law's kind of distance)
    over ``start_distance`` (``None``: the palm's at ``path[0]``, the start). The last
    row may be :data:`GRASP_POSITION_TOLERANCE` (and :data:`GRASP_ROTATION_TOLERANCE`)
    from the grasp pose, so the grasp pose may be that far from the one the plan was made
    for: a row's hand may be anything the law gives over the span of ``d`` that allows,
    plus :data:`HAND_TOLERANCE`.
    """
    hands = path[:, hand_idx]
    if law.fixed_clipped is not None:
        low = high = np.broadcast_to(law.fixed_clipped, hands.shape)
    else:
        grasp = pin.XYZQUATToSE3(grasp_pose)
        rotation_t = grasp.rotation.T if law.distance == "weighted" else None
        slack = GRASP_POSITION_TOLERANCE
        if rotation_t is not None:
            slack += law.rotation_weight * GRASP_ROTATION_TOLERANCE
        data = model.createData()
        raw = np.empty(len(path))
        for i, q in enumerate(path):
            pin.forwardKinematics(model, data, q)
            placement = pin.updateFramePlacement(model, data, palm_frame_id)
            raw[i] = palm_distance(placement, grasp.translation, rotation_t, law.rotation_weight)
        if start_distance is None:
            start_distance = float(raw[0])
            if start_distance < MIN_START_PALM_DISTANCE:
                raise ConfigError(
                    f"{where}path[0]",
                    f"the palm {start_distance * 1e3:.3g} mm from grasp_pose",
                    f"a start at least {MIN_START_PALM_DISTANCE * 1e3:g} mm from it (the"
                    " hand law's distance is normalised by it)",
                )
        # The law is affine in d on each side of mga, then clipped: over [d0, d1] each
        # joint's extremes lie at d0, d1 or mga.
        d = raw / start_distance
        d0 = np.maximum(d - slack / start_distance, 0.0)
        d1 = d + slack / start_distance
        ends = law.columns(np.concatenate([d0, d1, np.clip(law.mga, d0, d1)]))
        ends = ends.T.reshape(3, len(path), -1)
        low, high = ends.min(axis=0), ends.max(axis=0)
    bad = np.argwhere((hands < low - HAND_TOLERANCE) | (hands > high + HAND_TOLERANCE))
    if bad.size:
        i, j = (int(k) for k in bad[0])
        column = int(hand_idx[j])
        span = (
            f"{low[i, j]:.6g}"
            if high[i, j] - low[i, j] <= HAND_TOLERANCE
            else f"in [{low[i, j]:.6g}, {high[i, j]:.6g}]"
        )
        raise ConfigError(
            f"{where}path[{i}][{column}]",
            float(path[i, column]),
            f"{hand_joints[j]} at {span}, as the file's hand_law gives for the row's arm"
            " (robot.hand_joints in the law's order)",
        )


def _table(data: dict[str, Any], key: str, where: str, expected: str) -> dict[str, Any]:
    """``data[key]``, a table, or a ConfigError naming ``where + key``."""
    value = _key(data, key, where)
    if not isinstance(value, dict):
        raise ConfigError(f"{where}{key}", value, expected)
    return value


def _key(table: dict[str, Any], key: str, where: str) -> Any:
    """``table[key]``, or a ConfigError naming the missing ``where + key``."""
    if key not in table:
        raise ConfigError(f"{where}{key}", None, "a value (the key is missing)")
    return table[key]


def _urdf_model(urdf: str, where: str = "robot.urdf") -> pin.Model:
    if not Path(urdf).is_file():
        raise ConfigError(where, urdf, "an existing URDF file")
    return urdf_model(urdf, where)


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
        contents: The plan file's contents as read (JSON types): what a physics rollout
            builds its world from and an execution record keeps.
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
    contents: dict[str, Any] = field(repr=False)

    @classmethod
    def read(cls, path: str | Path) -> PlanFile:
        """Read a plan file, check it (:meth:`from_dict`) and load its robot's model.

        Raises:
            ConfigError: The file is not a readable ``openup-plan/1`` file, or what
                :meth:`from_dict` raises, located at ``<file name>: <key>``.
        """
        data = read_json(path, PLAN_FORMAT, "plan file")
        path = Path(path)
        return cls.from_dict(data, path.stem, where=f"{path.name}: ")

    @classmethod
    def from_dict(cls, data: dict[str, Any], name: str = "plan", where: str = "") -> PlanFile:
        """Check a plan file's contents (as :meth:`Plan.to_dict` gives them) and load
        its robot's model: the one check of every reader (``show``, ``execute``, the
        physics rollout, an execution file's ``source``).

        Args:
            data: The contents.
            name: A short name for titles.
            where: Prefix of error locations (e.g. ``"plan.json: "``).

        Raises:
            ConfigError: A key is missing or holds a bad value (a robot table naming
                joints or a frame its URDF lacks, an unloadable URDF, a bad law, shape or
                grasp pose, a path row of the wrong width, non-finite or beyond a joint
                limit by more than :data:`LIMIT_TOLERANCE`, a path that does not leave
                from ``start`` or does not end with the palm at ``grasp_pose``, within
                :data:`GRASP_POSITION_TOLERANCE` and :data:`GRASP_ROTATION_TOLERANCE`,
                a row whose hand is not the law's for its arm (:data:`HAND_TOLERANCE`),
                a ``start_palm_distance`` under :data:`MIN_START_PALM_DISTANCE`),
                located at ``where + key``.
        """
        if not isinstance(data, dict):
            raise ConfigError(where.rstrip(": .") or "plan", data, "a plan (a JSON object)")
        robot = _table(data, "robot", where, "a table with urdf, joint_names, palm_frame, ...")
        at = f"{where}robot."
        urdf = _toml.string(_key(robot, "urdf", at), f"{at}urdf")
        model = _urdf_model(urdf, f"{at}urdf")
        names = [model.names[i] for i in range(1, model.njoints) if model.joints[i].nq > 0]
        if _key(robot, "joint_names", at) != names:
            raise ConfigError(f"{at}joint_names", robot["joint_names"], f"{names} (the URDF's)")
        groups: dict[str, list[str]] = {}
        for key in ("arm_joints", "hand_joints"):
            groups[key] = _toml.string_list(_key(robot, key, at), f"{at}{key}")
            for joint in groups[key]:
                if joint not in names:
                    raise ConfigError(f"{at}{key}", joint, f"one of robot.joint_names {names}")
        shared = sorted(set(groups["arm_joints"]) & set(groups["hand_joints"]))
        if shared:
            raise ConfigError(f"{at}hand_joints", shared[0], "a joint not in robot.arm_joints")
        hand_joints = tuple(groups["hand_joints"])
        package_dirs = robot.get("package_dirs") or []
        if not (isinstance(package_dirs, list) and all(isinstance(d, str) for d in package_dirs)):
            raise ConfigError(f"{at}package_dirs", package_dirs, "a list of directories")
        palm = _toml.string(_key(robot, "palm_frame", at), f"{at}palm_frame")
        try:
            palm_frame_id = frame_id(model, palm)
        except FrameNotFound:
            raise ConfigError(f"{at}palm_frame", palm, f"a frame of {urdf}") from None
        hand_idx = np.array(
            [model.joints[model.getJointId(n)].idx_q for n in hand_joints], dtype=np.intp
        )
        table = _table(data, "hand_law", where, "a table with c, b, w, u, mga")
        law = HandLaw.from_table(
            table,
            model.lowerPositionLimit[hand_idx],
            model.upperPositionLimit[hand_idx],
            f"{where}hand_law",
            ignore=("start_palm_distance",),
        )
        start_distance = None
        if table.get("start_palm_distance") is not None:
            start_distance = _toml.number(
                table["start_palm_distance"],
                f"{where}hand_law.start_palm_distance",
                low=MIN_START_PALM_DISTANCE,
            )
        scene = _table(data, "scene", where, "a table with the object and obstacles")
        raw_obstacles = scene.get("obstacles") or []
        if not isinstance(raw_obstacles, list):
            raise ConfigError(f"{where}scene.obstacles", raw_obstacles, "a list of shape tables")
        obstacles = tuple(
            Shape.from_table(table, f"{where}scene.obstacles[{i}]")
            for i, table in enumerate(raw_obstacles)
        )
        raw_object = scene.get("object")
        shape = None
        if raw_object is not None:
            shape = Shape.from_table(raw_object, f"{where}scene.object", is_object=True)
        check_unique_names(obstacles, shape, f"{where}scene: obstacle name")
        for key in ("planner", "status"):
            if key in data:
                _toml.string(data[key], f"{where}{key}")
        seed = data.get("seed")
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, (int, np.integer))):
            raise ConfigError(f"{where}seed", seed, "an integer or null")
        if "solve_time_s" in data:
            _toml.number(data["solve_time_s"], f"{where}solve_time_s", low=0.0)
        start = None
        if "start" in data:
            start = _toml.vector(data["start"], f"{where}start", len(groups["arm_joints"]))
        grasp_pose = _toml.pose(_key(data, "grasp_pose", where), f"{where}grasp_pose")
        path = _path(_key(data, "path", where), f"{where}path", model)
        arm_idx = np.array(
            [model.joints[model.getJointId(n)].idx_q for n in groups["arm_joints"]], dtype=np.intp
        )
        _check_ends(path, start, arm_idx, model, palm_frame_id, grasp_pose, f"{where}")
        _check_hand(
            path,
            law,
            start_distance,
            model,
            hand_idx,
            hand_joints,
            palm_frame_id,
            grasp_pose,
            where,
        )
        return cls(
            name=name,
            planner=data.get("planner", "plan"),
            seed=None if seed is None else int(seed),
            status=data.get("status", ""),
            urdf=Path(urdf),
            package_dirs=tuple(package_dirs),
            model=model,
            hand_joints=hand_joints,
            hand_idx=hand_idx,
            palm_frame_id=palm_frame_id,
            law=law,
            grasp_pose=grasp_pose,
            path=path,
            obstacles=obstacles,
            object=shape,
            contents=data,
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
            contents=plan.to_dict(),
        )

    @property
    def grasp(self) -> pin.SE3:
        """Grasp pose of the palm frame as a Pinocchio ``SE3`` (world frame)."""
        return pin.XYZQUATToSE3(self.grasp_pose)
