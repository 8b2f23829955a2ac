"""Re-validation of a plan against its scene before it is used (``execute``, ``show``).

A plan file is text: it may be stale (made for another scene) or edited by hand. Before it
drives a robot, every state of its path is checked again with the planner's own checks
(:class:`~openup_ompl.validity.CoupledChecker`, which the OMPL validity checker and motion
validator wrap): joint limits, the hand on the law, consecutive states no farther apart
than the motion validator's resolution, and every motion between them collision-free by
the certified motion check. A plan made in this process and not written out need not be
checked again: the physics sweeps execute the plans they have just made without it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from openup_ompl._toml import is_finite
from openup_ompl.exceptions import ConfigError, PlanRejected, RobotNotFound
from openup_ompl.plan import Plan, PlanFile
from openup_ompl.robot import Robot, load_robot
from openup_ompl.scene import Problem
from openup_ompl.validity import DEFAULT_RESOLUTION, CoupledChecker

__all__ = ["Revalidation", "plan_problem", "revalidate_plan"]

#: Slack [rad or m] on a joint limit and on the law's hand (rounding only: the planner
#: writes the law's value itself, within the limits).
TOLERANCE = 1e-6
#: Relative slack on a step's displacement bound: the planner cuts a motion into steps
#: of exactly the resolution, which rounding may exceed by an ulp.
STEP_SLACK = 1e-6


@dataclass(frozen=True)
class Revalidation:
    """What a re-validation checked.

    Attributes:
        states: Path rows checked.
        motions: Motions between consecutive rows checked by the certified motion check.
        resolution: The motion validator's resolution used [m].
        largest_step: The largest displacement bound between consecutive rows [m].
    """

    states: int
    motions: int
    resolution: float
    largest_step: float


def _robot_of(plan: PlanFile, where: str) -> Robot:
    """The robot of a plan file: loaded from the robot file it names (``robot.file``) if
    that is still there, else by its name among the shipped robots; its joints must be
    the file's."""
    table = plan.contents.get("robot", {})
    name, file = table.get("name"), table.get("file")
    source = file if isinstance(file, str) and Path(file).is_file() else name
    try:
        robot = load_robot(source)
    except RobotNotFound:
        raise ConfigError(
            f"{where}robot.name",
            name,
            "a shipped robot, or a robot.file that exists, to re-validate the plan against",
        ) from None
    if robot.joint_names != table.get("joint_names") or robot.hand_joints != plan.hand_joints:
        raise ConfigError(
            f"{where}robot.joint_names",
            table.get("joint_names"),
            f"the joints of robot {source!r}: {robot.joint_names}",
        )
    return robot


def plan_problem(plan: PlanFile, where: str = "") -> Problem:
    """The problem a plan file was made for, rebuilt from the file alone: its robot (its
    ``robot.file``, else by name), start (its first row), grasp pose, hand law, obstacles
    and object.

    Args:
        plan: The plan file, read and checked (:meth:`PlanFile.read`).
        where: Prefix of error locations (e.g. ``"plan.json: "``).

    Returns:
        The problem, ready for :class:`~openup_ompl.validity.CoupledChecker`.

    Raises:
        ConfigError: The robot is unknown here, or its joints differ from the file's.
    """
    robot = _robot_of(plan, where)
    start = plan.path[0, robot.arm_idx]
    return Problem(robot, start, plan.grasp_pose, plan.law, list(plan.obstacles), plan.object, None)


def _first(mask: np.ndarray) -> int:
    """Index of the first true entry of ``mask``, or its length if none."""
    hits = np.flatnonzero(mask)
    return int(hits[0]) if hits.size else len(mask)


def _recorded(plan: Plan | PlanFile, key: str, default: float | None, where: str) -> float | None:
    """The checker setting ``key`` [m] the plan's ``stats`` record (the planner's), else
    ``default``."""
    stats = plan.stats if isinstance(plan, Plan) else plan.contents.get("stats")
    value = stats.get(key) if isinstance(stats, dict) else None
    if value is None:
        return default
    if not is_finite(value) or value < 0:
        raise ConfigError(f"{where}stats.{key}", value, "a length >= 0 [m]")
    return float(value)


def _cheap_refusal(
    path: np.ndarray, checker: CoupledChecker, steps: np.ndarray
) -> tuple[int, str, str] | None:
    """The first row beyond a joint limit, off the law or too far from the row before it:
    ``(row, reason, expected)``, or ``None``."""
    robot = checker.robot
    columns = np.r_[robot.arm_idx, robot.hand_idx]
    low = robot.model.lowerPositionLimit[columns] - TOLERANCE
    high = robot.model.upperPositionLimit[columns] + TOLERANCE
    beyond = (path[:, columns] < low) | (path[:, columns] > high)
    law_hands = checker.coupled_qs(path[:, robot.arm_idx]).T[:, robot.hand_idx]
    off = np.abs(path[:, robot.hand_idx] - law_hands)
    rows = (
        _first(beyond.any(axis=1)),
        _first((off > TOLERANCE).any(axis=1)),
        _first(steps > checker.resolution * (1.0 + STEP_SLACK)),
    )
    row = min(rows)
    if row == len(path):
        return None
    if row == rows[0]:
        column = int(columns[np.flatnonzero(beyond[row])[0]])
        names = robot.joint_names
        name = names[column] if len(names) == path.shape[1] else f"q[{column}]"
        return row, f"{name} = {path[row, column]:.6g}", "every joint within its limits"
    if row == rows[1]:
        return (
            row,
            f"a hand {float(off[row].max()):.3g} from the law's for its arm",
            "the hand the plan's hand_law gives (within 1e-6)",
        )
    return (
        row,
        f"a robot point may move {steps[row] * 1e3:.1f} mm from path[{row - 1}]",
        f"consecutive states at most {checker.resolution * 1e3:g} mm apart (the motion"
        " validator's resolution)",
    )


def revalidate_plan(
    plan: Plan | PlanFile,
    problem: Problem | None = None,
    *,
    resolution: float | None = None,
    where: str = "",
) -> Revalidation:
    """Re-validate a plan against its scene, in path order; refuse the first bad state.

    Args:
        plan: A plan in memory or a plan file read.
        problem: The scene to check against (default: the plan's own: ``plan.problem``,
            or :func:`plan_problem` for a file).
        resolution: The motion validator's resolution [m] (default: the planner's, which
            the plan's ``stats["resolution"]`` records, else
            :data:`~openup_ompl.validity.DEFAULT_RESOLUTION`); its padding is the
            planner's too (``stats["padding"]``).
        where: Prefix of error locations (e.g. ``"plan.json: "``).

    Returns:
        What was checked.

    Raises:
        PlanRejected: Naming the first path row that leaves the joint limits, whose hand
            is not the law's for its arm, that lies farther than ``resolution`` from the
            row before it, or whose motion from the row before it collides.
        ConfigError: The robot of a plan file cannot be loaded here; a bad recorded
            resolution or padding.
    """
    if problem is None:
        problem = plan.problem if isinstance(plan, Plan) else plan_problem(plan, where)
    if resolution is None:
        resolution = _recorded(plan, "resolution", None, where) or DEFAULT_RESOLUTION
    padding = _recorded(plan, "padding", None, where)
    checker = CoupledChecker(problem, plan.law, resolution=resolution, padding=padding)
    path = np.asarray(plan.path, dtype=float)
    arms = path[:, problem.robot.arm_idx]
    steps = np.zeros(len(path))
    for i in range(1, len(path)):
        steps[i] = float(np.abs(arms[i] - arms[i - 1]) @ checker.weights(arms[i - 1], arms[i]))
    refusal = _cheap_refusal(path, checker, steps)
    first_bad = len(path) if refusal is None else refusal[0]
    # The motions before the first cheaply refused row, in path order.
    for i in range(1, first_bad):
        if not checker.check_motion(arms[i - 1], arms[i]):
            raise PlanRejected(
                where, i, f"the motion from path[{i - 1}] collides", "a collision-free path"
            )
    if refusal is not None:
        raise PlanRejected(where, *refusal)
    largest = float(steps.max()) if len(path) > 1 else 0.0
    return Revalidation(len(path), max(len(path) - 1, 0), checker.resolution, largest)
