"""An independent re-check of plan files, as a user would write it from the CONTRACT.

Built only from the plan file: its URDF, SRDF and package directories, the scene shapes it
repeats, the hand law it records. Collision meshes stay meshes (the planner uses convex
hulls, which contain them), the hand comes from the paper's formula written out here, and
every segment is re-interpolated finer than the planner checked it.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import coal
import numpy as np
import pinocchio as pin

_THREADS = max(1, len(os.sched_getaffinity(0)))


def paper_open_hand(d: float, law: dict[str, Any]) -> np.ndarray:
    """Algorithm 3, written from the paper (and the CONTRACT's continuous variant)."""
    c, b, w = (np.array(law[k]) for k in ("c", "b", "w"))
    u, mga = law["u"], law["mga"]
    if law.get("fixed") is not None:
        return np.array(law["fixed"])
    if d <= mga and law.get("open_arrival"):
        arrival, plateau = c + (w - c) * u, b + (w - b) * u
        return arrival + (d / mga) * (plateau - arrival)
    if d <= mga:
        far = (w - b) if law["continuous"] else (w - c)
        return c + (d / mga) * ((b - c) + far * u)
    return b + (w - b) * u


@dataclass
class Recheck:
    """Outcome of re-checking one plan."""

    states: int
    colliding: list[int]
    hand_error: float
    position_error: float
    rotation_error: float
    start_error: float


def _shape_geometry(shape: dict[str, Any]) -> coal.CollisionGeometry:
    if shape["shape"] == "mesh":  # the convex hull of the file's vertices, by Coal itself
        scale = np.full(3, float(shape.get("scale", 1.0)))
        mesh = coal.MeshLoader().load(shape["file"], scale)
        mesh.buildConvexRepresentation(True)
        return mesh.convex
    if shape["shape"] == "box":
        return coal.Box(*shape["size"])
    if shape["shape"] == "sphere":
        return coal.Sphere(shape["radius"])
    return coal.Cylinder(shape["radius"], shape["length"])


def recheck_plan(plan: dict[str, Any], finer: int = 10, resolution: float = 0.015) -> Recheck:
    """Re-check a plan file's path: collisions at ``resolution / finer``, the hand against
    the law at every row, the start and the final palm pose."""
    robot = plan["robot"]
    model = pin.buildModelFromUrdf(robot["urdf"])
    geometry = pin.buildGeomFromUrdf(
        model, robot["urdf"], pin.COLLISION, package_dirs=robot["package_dirs"]
    )
    geometry.addAllCollisionPairs()
    if robot["srdf"]:
        pin.removeCollisionPairs(model, geometry, robot["srdf"])
    n_robot = geometry.ngeoms
    shapes = list(plan["scene"]["obstacles"])
    if plan["scene"]["object"]:
        shapes.append(plan["scene"]["object"])
    for shape in shapes:
        placement = pin.XYZQUATToSE3(np.array(shape["pose"], dtype=float))
        geometry.addGeometryObject(
            pin.GeometryObject("env_" + shape["name"], 0, 0, placement, _shape_geometry(shape))
        )
    for env in range(n_robot, geometry.ngeoms):
        for link in range(n_robot):
            geometry.addCollisionPair(pin.CollisionPair(link, env))
    data, geometry_data = model.createData(), geometry.createData()

    names = robot["joint_names"]
    arm_q = [model.joints[model.getJointId(n)].idx_q for n in robot["arm_joints"]]
    hand_q = [model.joints[model.getJointId(n)].idx_q for n in robot["hand_joints"]]
    assert names == [model.names[i] for i in range(1, model.njoints) if model.joints[i].nq > 0]
    palm = model.getFrameId(robot["palm_frame"])
    grasp = pin.XYZQUATToSE3(np.array(plan["grasp_pose"], dtype=float))
    law = plan["hand_law"]
    lower = model.lowerPositionLimit[hand_q]
    upper = model.upperPositionLimit[hand_q]

    def palm_pose(q: np.ndarray) -> pin.SE3:
        pin.forwardKinematics(model, data, q)
        return pin.updateFramePlacement(model, data, palm)

    def law_hand(q: np.ndarray) -> np.ndarray:
        # Algorithm 1's D: the palm's distance to the grasp, plus (the CONTRACT's
        # "weighted" variant) rotation_weight times the angle between their orientations.
        placement = palm_pose(q)
        d = float(np.linalg.norm(placement.translation - grasp.translation))
        if law.get("distance", "translation") == "weighted":
            angle = float(np.linalg.norm(pin.log3(grasp.rotation.T @ placement.rotation)))
            d += law["rotation_weight"] * angle
        d /= law["start_palm_distance"]
        return np.clip(paper_open_hand(d, law), lower, upper)

    path = np.array(plan["path"], dtype=float)
    hand_error = max(float(np.max(np.abs(row[hand_q] - law_hand(row)))) for row in path)
    # Every segment re-interpolated at resolution / finer, each shared end state once; the
    # whole path then goes to Pinocchio's parallel pair loop in one batch (meshes, no GJK
    # warm start, so no answer depends on the query before it).
    first = path[0].copy()
    first[hand_q] = law_hand(first)
    columns, segment_of = [first], [0]
    for i in range(len(path) - 1):
        a, b = path[i, arm_q], path[i + 1, arm_q]
        steps = max(1, math.ceil(float(np.linalg.norm(b - a)) / (resolution / finer)))
        for k in range(1, steps + 1):
            q = path[i].copy()
            q[arm_q] = a + (b - a) * (k / steps)
            q[hand_q] = law_hand(q)
            columns.append(q)
            segment_of.append(i)
    pool = pin.GeometryPool(model, geometry, _THREADS)
    for geometry_data in pool.getGeometryDatas():
        for request in geometry_data.collisionRequests:
            request.gjk_initial_guess = coal.GJKInitialGuess.DefaultGuess
    hits = pin.computeCollisionsInParallel(
        _THREADS, pool, np.asfortranarray(np.array(columns).T), True, False
    )
    colliding = sorted({segment_of[k] for k in np.flatnonzero(hits)})
    states = len(columns)
    final = palm_pose(path[-1])
    error = pin.log6(final.actInv(grasp)).vector
    return Recheck(
        states=states,
        colliding=colliding,
        hand_error=hand_error,
        position_error=float(np.linalg.norm(final.translation - grasp.translation)),
        rotation_error=float(np.linalg.norm(error[3:])),
        start_error=float(np.max(np.abs(path[0, arm_q] - np.array(plan["start"])))),
    )


def assert_plan_rechecks(plan: Any, directory: Path) -> None:
    """Save a plan (an ``openup_ompl.Plan``), reload its file and re-check it: start, grasp
    pose, hand law, no collision."""
    data = json.loads(plan.save(directory / f"{plan.planner}-{plan.seed}.json").read_text())
    result = recheck_plan(data)
    assert result.start_error < 1e-9
    assert result.colliding == [], f"seed {plan.seed}: segments {result.colliding} collide"
    assert result.position_error <= 1e-3
    assert result.rotation_error <= 1e-2
    assert result.hand_error < 1e-9


def solved_and_rechecked(
    setup: Any, planner: str, seeds: range, time_limit: float, directory: Path
) -> int:
    """How many seeds ``setup.solve`` (a ``GraspPlanningSetup``) solves; every plan it
    returns must pass :func:`assert_plan_rechecks`."""
    from openup_ompl import PlanningFailed

    solved = 0
    for seed in seeds:
        try:
            plan = setup.solve(time_limit=time_limit, planner=planner, seed=seed)
        except PlanningFailed:
            continue
        solved += 1
        assert_plan_rechecks(plan, directory)
    return solved
