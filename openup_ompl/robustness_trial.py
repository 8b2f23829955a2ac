"""One trial of the robustness experiment: a plan made at the nominal object pose
(:func:`plan_nominal`), then executed against the object where it really is
(:func:`displaced`, :func:`execute`): every row re-checked against the true scene, the
hand closed at the end, the grasp judged by force closure.

:func:`robustness_run` is the task a sweep's process runs
(:mod:`~openup_ompl.robustness` makes the tasks and gathers their records).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from openup_ompl.collision import CollisionWorld
from openup_ompl.exceptions import InvalidProblem, PlanningFailed
from openup_ompl.grasp import (
    GraspResult,
    HandCloser,
    closed_configuration,
    enclosed,
    force_closure,
    object_axis,
)
from openup_ompl.plan import Plan
from openup_ompl.planning import GraspPlanningSetup
from openup_ompl.planning_options import PlanningOptions
from openup_ompl.scene import Problem, load_scene


def displaced(problem: Problem, dx: float, dy: float, yaw: float = 0.0) -> Problem:
    """The problem with its object moved by ``(dx, dy)`` in the world frame and turned by
    ``yaw`` about its own z axis: where the object really is.

    Args:
        problem: The nominal problem.
        dx, dy: Position error [m] along the world x and y axes.
        yaw: Rotation error [rad] about the object's own z axis.

    Returns:
        A copy of ``problem`` whose object is at the displaced pose (the obstacles and
        grasp pose unchanged).

    Raises:
        InvalidProblem: The scene has no ``[object]``.
    """
    shape = problem.object
    if shape is None:
        raise InvalidProblem("the scene has no [object] to displace")
    placement = shape.placement
    turned = placement.rotation @ pin.utils.rotate("z", float(yaw))
    pose = pin.SE3ToXYZQUAT(
        pin.SE3(turned, placement.translation + np.array([float(dx), float(dy), 0.0]))
    )
    return dataclasses.replace(problem, object=shape.at(pose))


def check_scene(scene: str | Path) -> Problem:
    """Load a scene and refuse what the experiment cannot run on.

    Args:
        scene: The scene file.

    Returns:
        The loaded problem.

    Raises:
        InvalidProblem: No ``[object]``, a robot without hand joints, or a hand that has
            no joint to close.
    """
    problem = load_scene(scene)
    if problem.object is None:
        raise InvalidProblem(f"{Path(scene).name}: the scene has no [object] to grasp")
    closed = closed_configuration(problem)
    if np.all(np.isnan(closed)):
        raise InvalidProblem(
            f"robot {problem.robot.name!r}: no hand joint closes (c == w everywhere and no"
            " [hand].closed)"
        )
    return problem


def plan_nominal(
    seed: int,
    scene: str,
    u: float,
    planner: str,
    time_limit: float,
    perturbations: Sequence[Sequence[float]],
    open_arrival: bool,
    failed: dict[str, Any],
) -> tuple[dict[str, Any], GraspPlanningSetup | None, Plan | None]:
    """A sweep task's plan, made once at the nominal pose (shared by the kinematic and
    the physics execution).

    Args:
        seed: The planning seed.
        scene: The scene file.
        u: The hand law's ``u`` (unitless, in ``[0, 1]``).
        planner: A planner name (:data:`~openup_ompl.planning_options.PLANNERS`).
        time_limit: Planning time [s].
        perturbations: The ``(dx [m], dy [m], yaw [rad])`` cells the plan is executed at.
        open_arrival: Plan with the law's open-arrival variant.
        failed: The execution's own trial fields, as a failed trial holds them.

    Returns:
        The task's record (``u, seed, planned, error``; with ``solve_time, rows`` once
        planned), the setup and the plan. A planning failure gives ``None`` for both and
        fills the record's ``trials``: every perturbation failed, each with ``failed``'s
        keys (the execution's own fields) besides ``dx, dy, yaw, success, collision``.
    """
    problem = check_scene(scene)
    record: dict[str, Any] = {"u": u, "seed": seed, "planned": False, "error": None}
    try:
        options = PlanningOptions(
            u=u, open_arrival=open_arrival, planner=planner, time_limit=time_limit, simplify=True
        )
        setup = GraspPlanningSetup(problem, options)
        plan = setup.solve(seed=seed)
    except (PlanningFailed, InvalidProblem) as error:
        record["error"] = str(error)
        record["trials"] = [
            {"dx": c[0], "dy": c[1], "yaw": c[2], "success": False, "collision": False, **failed}
            for c in perturbations
        ]
        return record, None, None
    record.update(planned=True, solve_time=plan.solve_time_s, rows=int(plan.path.shape[0]))
    return record, setup, plan


def robustness_run(
    seed: int,
    scene: str,
    u: float,
    planner: str,
    time_limit: float,
    perturbations: Sequence[Sequence[float]],
    friction: float,
    open_arrival: bool = False,
    torsion: float | None = None,
) -> dict[str, Any]:
    """Plan once at the nominal pose, then execute against every perturbation (inside a
    task process).

    Args:
        seed, scene, u, planner, time_limit, perturbations, open_arrival: As for
            :func:`plan_nominal`.
        friction: Coulomb friction coefficient of the finger contacts (unitless).
        torsion: Soft-finger torsional friction lever [m]; ``None``: the robot's.

    Returns:
        ``{"u", "seed", "planned", "error", "solve_time", "trials": [...]}``; each trial
        has ``dx, dy, yaw, collision, collision_row, pairs, force_closure, enclosed,
        contacts, fingers, success``.
    """
    record, setup, plan = plan_nominal(
        seed, scene, u, planner, time_limit, perturbations, open_arrival,
        failed={"force_closure": False, "enclosed": False},
    )  # fmt: skip
    if setup is None or plan is None:
        return record
    torsion = setup.problem.robot.spec.torsion if torsion is None else torsion
    record["trials"] = [
        execute(setup, plan, dx, dy, yaw, friction=friction, torsion=torsion)[0]
        for dx, dy, yaw in perturbations
    ]
    return record


def execute(
    setup: GraspPlanningSetup,
    plan: Plan,
    dx: float,
    dy: float,
    yaw: float = 0.0,
    *,
    friction: float = 0.5,
    torsion: float = 0.0,
) -> tuple[dict[str, Any], GraspResult]:
    """Execute one plan against the object displaced by ``(dx, dy, yaw)``: re-check every
    row against the true scene, then close the hand at the end of the plan.

    Args:
        setup: The setup the plan was made with (nominal object pose).
        plan: The plan.
        dx, dy: Position error [m] along the world x and y axes.
        yaw: Rotation error [rad] about the object's own z axis.
        friction: Coulomb friction coefficient of the finger contacts (unitless).
        torsion: Soft-finger torsional friction lever [m] (``0``: point contacts).

    Returns:
        The trial (``dx, dy, yaw, collision, collision_row, collision_d, pairs,
        force_closure, enclosed, contacts, fingers, success``) and the closed hand.
    """
    problem = setup.problem
    true = displaced(problem, dx, dy, yaw)
    assert true.object is not None
    world = CollisionWorld(true, num_threads=1)
    flags = world.batch_in_collision(np.asfortranarray(plan.path.T), stop_at_first=False)
    hit = int(np.argmax(flags)) if flags.any() else None
    grasp = HandCloser(true).close(plan.path[-1])
    closure = len(grasp.contacts) > 0 and force_closure(
        grasp.points, grasp.normals, friction=friction, torsion=torsion
    )
    trial = {
        "dx": dx,
        "dy": dy,
        "yaw": yaw,
        "collision": hit is not None,
        "collision_row": hit,
        # Algorithm 1's d where the plan first touches: how far from the grasp.
        "collision_d": None
        if hit is None
        else setup.checker.normalized_distance(plan.path[hit, problem.robot.arm_idx]),
        "pairs": world.colliding_pairs(plan.path[hit]) if hit is not None else [],
        "force_closure": bool(closure),
        "enclosed": enclosed(grasp.normals, object_axis(true.object)),
        "contacts": len(grasp.contacts),
        "fingers": sorted(grasp.fingers),
        "success": hit is None and bool(closure),
    }
    return trial, grasp
