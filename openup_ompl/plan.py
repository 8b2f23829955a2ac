"""Plans: the result of a solve, and the plan file (CONTRACT §4)."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from openup_ompl._io import write_atomic
from openup_ompl.exceptions import ConfigError
from openup_ompl.hand_law import HandLaw
from openup_ompl.scene import Problem

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
        """The plan file's contents (CONTRACT §4)."""
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
        """Write the plan file (JSON, CONTRACT §4); returns its path."""
        path = Path(path)
        if not np.all(np.isfinite(self.path)):
            raise ConfigError("plan path", "non-finite values", "a finite path")
        return write_atomic(path, json.dumps(self.to_dict(), indent=1, allow_nan=False))


def read_plan(path: str | Path) -> dict[str, Any]:
    """Read a plan file and check its format and path shape."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as error:
        raise ConfigError("plan file", str(path), f"a readable JSON plan ({error})") from None
    if not isinstance(data, dict) or data.get("format") != PLAN_FORMAT:
        raise ConfigError(
            f"{path.name}: format",
            data.get("format") if isinstance(data, dict) else data,
            PLAN_FORMAT,
        )
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
