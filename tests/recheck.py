"""An independent re-check of plan files, as a user would write it from the CONTRACT.

Built only from the plan file: its URDF, SRDF and package directories, the scene shapes it
repeats, the hand law it records. Collision meshes stay meshes (the planner uses convex
hulls, which contain them), the hand comes from the paper's formula written out here, and
every segment is re-interpolated finer than the planner checked it. The states' collision
checks go to Pinocchio and Coal in one batch, through Coal's broad phase (which the tests
hold to Pinocchio's every-pair loop); the robot's model is built once per process.
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


def paper_open_hand(d: np.ndarray, law: dict[str, Any]) -> np.ndarray:
    """Algorithm 3, written from the paper (and the CONTRACT's continuous variant): the
    hand at each normalised distance of ``d`` (one row per distance)."""
    c, b, w = (np.array(law[k]) for k in ("c", "b", "w"))
    u, mga = law["u"], law["mga"]
    d = np.asarray(d, dtype=float)[:, None]
    if law.get("fixed") is not None:
        return np.broadcast_to(np.array(law["fixed"]), (len(d), len(c)))
    if law.get("open_arrival"):
        arrival, plateau = c + (w - c) * u, b + (w - b) * u
        near = arrival + (d / mga) * (plateau - arrival)
    else:
        far = (w - b) if law["continuous"] else (w - c)
        near = c + (d / mga) * ((b - c) + far * u)
    return np.where(d <= mga, near, b + (w - b) * u)


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


def _robot_geometry(robot: dict[str, Any]) -> tuple[pin.Model, pin.GeometryModel]:
    """The robot's kinematic model and collision geometry (the SRDF's pairs removed), from
    its URDF, SRDF and package directories; built again whenever their paths or texts
    differ from an earlier plan's in this process."""
    files = [robot["urdf"], robot["srdf"]]
    texts = [Path(f).read_text() if f else "" for f in files]
    key = json.dumps([files, texts, robot["package_dirs"]])
    if key not in _ROBOTS:
        model = pin.buildModelFromUrdf(robot["urdf"])
        geometry = pin.buildGeomFromUrdf(
            model, robot["urdf"], pin.COLLISION, package_dirs=robot["package_dirs"]
        )
        geometry.addAllCollisionPairs()
        if robot["srdf"]:
            pin.removeCollisionPairs(model, geometry, robot["srdf"])
        _ROBOTS[key] = model, geometry
    return _ROBOTS[key]


_ROBOTS: dict[str, tuple[pin.Model, pin.GeometryModel]] = {}


def plan_geometry(plan: dict[str, Any]) -> tuple[pin.Model, pin.GeometryModel]:
    """The plan file's robot and its collision geometry with the scene's shapes added,
    every robot geometry paired with every scene shape."""
    model, robot_geometry = _robot_geometry(plan["robot"])
    geometry = pin.GeometryModel(robot_geometry)  # a copy: the scene is this plan's
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
    return model, geometry


def colliding_states(
    model: pin.Model, geometry: pin.GeometryModel, states: np.ndarray
) -> np.ndarray:
    """Whether each state (a row of ``states``) has a colliding pair: all states in one
    batch to Pinocchio's parallel loop, through a Coal broad phase (an AABB tree: only
    pairs whose boxes overlap reach the narrow phase; meshes, no GJK warm start, so no
    answer depends on the query before it)."""
    pool = pin.BroadPhaseManagerPool_DynamicAABBTreeCollisionManager(model, geometry, _THREADS)
    for geometry_data in pool.getGeometryDatas():
        for request in geometry_data.collisionRequests:
            request.gjk_initial_guess = coal.GJKInitialGuess.DefaultGuess
    batch = np.asfortranarray(np.asarray(states, dtype=float).T)
    return np.asarray(pin.computeCollisionsInParallel(_THREADS, pool, batch, True), dtype=bool)


def recheck_plan(plan: dict[str, Any], finer: int = 10, resolution: float = 0.015) -> Recheck:
    """Re-check a plan file's path: collisions at ``resolution / finer``, the hand against
    the law at every row, the start and the final palm pose."""
    robot = plan["robot"]
    model, geometry = plan_geometry(plan)
    data = model.createData()

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

    def law_hand(rows: np.ndarray) -> np.ndarray:
        # Algorithm 1's D: the palm's distance to the grasp, plus (the CONTRACT's
        # "weighted" variant) rotation_weight times the angle between their orientations.
        weighted = law.get("distance", "translation") == "weighted"
        positions, angles = np.empty((len(rows), 3)), np.zeros(len(rows))
        for k, q in enumerate(rows):
            placement = palm_pose(q)
            positions[k] = placement.translation
            if weighted:
                angles[k] = np.linalg.norm(pin.log3(grasp.rotation.T @ placement.rotation))
        d = np.linalg.norm(positions - grasp.translation, axis=1)
        if weighted:
            d += law["rotation_weight"] * angles
        return np.clip(paper_open_hand(d / law["start_palm_distance"], law), lower, upper)

    path = np.array(plan["path"], dtype=float)
    hand_error = float(np.max(np.abs(path[:, hand_q] - law_hand(path))))
    # Every segment re-interpolated at resolution / finer (the arm joints; the rest of the
    # row held), each shared end state once, and the hand set by the law at every state.
    lengths = np.linalg.norm(np.diff(path[:, arm_q], axis=0), axis=1)  # [rad]
    steps = [max(1, math.ceil(length / (resolution / finer))) for length in lengths]
    segment_of = np.repeat(np.arange(len(steps)), steps)  # of each interpolated state
    fraction = np.concatenate([np.arange(1, n + 1) / n for n in steps])
    start, end = path[segment_of][:, arm_q], path[segment_of + 1][:, arm_q]
    segment_of = np.concatenate([[0], segment_of])  # path[0] first, as segment 0's
    columns = path[segment_of].copy()
    columns[1:, arm_q] = start + (end - start) * fraction[:, None]
    columns[:, hand_q] = law_hand(columns)
    hits = colliding_states(model, geometry, columns)
    colliding = sorted({int(segment_of[k]) for k in np.flatnonzero(hits)})
    final = palm_pose(path[-1])
    error = pin.log6(final.actInv(grasp)).vector
    return Recheck(
        states=len(columns),
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
