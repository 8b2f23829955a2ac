"""What a rollout takes of a plan (:class:`PlanInput`): from a plan in memory its problem's
robot and scene as they are, from a plan file what the file holds; no round trip through
the file format in process."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from openup_ompl.exceptions import ConfigError
from openup_ompl.physics.robot_table import RobotTable, robot_spec
from openup_ompl.scene import Shape

if TYPE_CHECKING:
    from openup_ompl.plan import Plan, PlanFile
    from openup_ompl.robot_file import RobotSpec

__all__ = ["PlanInput"]


@dataclass(frozen=True, eq=False)
class PlanInput:
    """What a rollout takes of a plan: the robot, the scene, the law's ends, the path.

    Attributes:
        robot: The robot's files and joint groups.
        spec: Its robot file (``[hand].closed``, ``closing_speed``), or ``None``.
        obstacles: The scene's obstacles (movable ones become free bodies).
        object: The object, at its nominal pose.
        c: The law's close preshape (one value per hand joint).
        w: The law's widest configuration.
        u: The law's ``u`` (recorded).
        start_palm_distance: Palm-to-grasp distance at the start [m] (0: unknown).
        path: ``(N, n)`` rows in the robot's joint order.
        grasp_pose: The palm's target ``[x, y, z, qx, qy, qz, qw]``.
        planner: The planner's name (recorded).
        seed: The planning seed (recorded).
        contents: Makes the plan file's contents (kept in a record with frames).
    """

    robot: RobotTable
    spec: RobotSpec | None
    obstacles: tuple[Shape, ...]
    object: Shape
    c: np.ndarray
    w: np.ndarray
    u: Any
    start_palm_distance: float
    path: np.ndarray
    grasp_pose: np.ndarray
    planner: Any
    seed: Any
    contents: Callable[[], dict[str, Any]]

    @classmethod
    def from_plan(cls, plan: Plan, scene_object: Shape | None = None) -> PlanInput:
        """A plan in memory, with its problem's robot (its robot file as loaded) and
        scene.

        Args:
            plan: The plan.
            scene_object: The object where it really is (the world's truth); ``None``:
                the problem's object.

        Returns:
            The rollout's input.

        Raises:
            ConfigError: No object to grasp.
        """
        problem = plan.problem
        target = scene_object if scene_object is not None else problem.object
        if target is None:
            raise ConfigError("plan scene.object", None, "an object to grasp")
        law = plan.law.to_dict()

        def contents() -> dict[str, Any]:
            data = plan.to_dict()
            if scene_object is not None:
                data["scene"] = {**data["scene"], "object": scene_object.to_table()}
            return data

        return cls(
            robot=RobotTable.from_robot(problem.robot),
            spec=problem.robot.spec,
            obstacles=tuple(problem.obstacles),
            object=target,
            c=np.asarray(law["c"], dtype=float),
            w=np.asarray(law["w"], dtype=float),
            u=law.get("u"),
            start_palm_distance=float(plan.start_palm_distance or 0.0),
            path=plan.path,
            grasp_pose=np.asarray(problem.grasp_pose, dtype=float),
            planner=plan.planner,
            seed=plan.seed,
            contents=contents,
        )

    @classmethod
    def from_file(cls, plan: PlanFile) -> PlanInput:
        """A plan file as read (:meth:`~openup_ompl.plan.PlanFile.read`); its robot file
        is found by its robot's name.

        Args:
            plan: The plan file.

        Returns:
            The rollout's input.

        Raises:
            ConfigError: No object to grasp, or the law's ``c``/``w`` are not numbers.
        """
        data = plan.contents
        if plan.object is None:
            raise ConfigError("plan scene.object", None, "an object to grasp")
        robot = RobotTable.from_table(data.get("robot") or {})
        law = data.get("hand_law") or {}
        try:
            c = np.asarray(law.get("c", []), dtype=float)
            w = np.asarray(law.get("w", []), dtype=float)
        except (TypeError, ValueError):
            raise ConfigError("plan hand_law c/w", law.get("c"), "hand joint values") from None
        return cls(
            robot=robot,
            spec=robot_spec(robot.name),
            obstacles=tuple(plan.obstacles),
            object=plan.object,
            c=c,
            w=w,
            u=law.get("u"),
            start_palm_distance=float(law.get("start_palm_distance") or 0.0),
            path=plan.path,
            grasp_pose=plan.grasp_pose,
            planner=data.get("planner"),
            seed=data.get("seed"),
            contents=lambda: data,
        )
