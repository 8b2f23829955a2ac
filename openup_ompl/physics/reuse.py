"""Compiled worlds reused within a process: a rollout of a plan whose robot, options and
scene (but for the object's and the neighbours' poses) were compiled before takes a copy
of that model instead of compiling it again (:func:`cached_world`)."""

from __future__ import annotations

import dataclasses
import json
from collections import OrderedDict
from collections.abc import Sequence
from typing import Any

import numpy as np

from openup_ompl.physics.options import PhysicsOptions
from openup_ompl.physics.shapes import mujoco_quat
from openup_ompl.physics.world import RobotTable, World, make_world
from openup_ompl.scene import Shape

__all__ = ["CACHE_SIZE", "cached_world", "clear_cache"]

#: Compiled worlds kept per process (the most recently used).
CACHE_SIZE = 8
_CACHE: OrderedDict[str, World] = OrderedDict()


def clear_cache() -> None:
    """Forget every kept world."""
    _CACHE.clear()


def _key(
    robot: RobotTable, obstacles: Sequence[Shape], scene_object: Shape, options: PhysicsOptions
) -> str:
    """What the compiled model depends on: the robot, its pads, the options, the fixed
    obstacles, and the object and neighbours without their poses (a free body's pose is
    its state, set at each start)."""

    def plain(value: Any) -> Any:
        return value.tolist() if isinstance(value, np.ndarray) else str(value)

    def shape(s: Shape) -> dict[str, Any]:
        table = s.to_table()
        if s.movable or s is scene_object:
            table.pop("pose")
        return table

    return json.dumps(
        {
            "robot": dataclasses.asdict(robot),
            "options": dataclasses.asdict(options),
            "obstacles": [shape(s) for s in obstacles],
            "object": shape(scene_object),
        },
        default=plain,
        sort_keys=True,
    )


def cached_world(
    robot: RobotTable,
    obstacles: Sequence[Shape],
    scene_object: Shape,
    options: PhysicsOptions,
) -> World:
    """:func:`~openup_ompl.physics.world.make_world`, compiled once per key
    (:func:`_key`) and process: later calls get a copy of the kept model (a rollout may
    change its copy) with this call's object and neighbour poses.

    Args:
        robot, obstacles, scene_object, options: As for
            :func:`~openup_ompl.physics.world.make_world`.

    Returns:
        A world of its own, its object and neighbours at this call's poses.

    Raises:
        ConfigError: What :func:`~openup_ompl.physics.world.make_world` raises.
    """
    import copy

    key = _key(robot, obstacles, scene_object, options)
    kept = _CACHE.get(key)
    if kept is None:
        kept = _CACHE[key] = make_world(robot, obstacles, scene_object, options)
        while len(_CACHE) > CACHE_SIZE:
            _CACHE.popitem(last=False)
    else:
        _CACHE.move_to_end(key)
    world = kept
    neighbours = [s for s in obstacles if s.movable]
    start = world.neighbour_start.copy()
    for i, (old, new) in enumerate(zip(world.neighbours, neighbours, strict=True)):
        if not np.array_equal(old.pose, new.pose):
            quat = mujoco_quat(new.pose)
            start[i] = [*np.asarray(new.pose[:3], dtype=float), *(quat / np.linalg.norm(quat))]
    shaped = scene_object
    if options.object_mass is not None:
        shaped = dataclasses.replace(shaped, mass=options.object_mass)
    if options.object_friction is not None:
        shaped = dataclasses.replace(shaped, friction=options.object_friction)
    return dataclasses.replace(
        world,
        model=copy.copy(world.model),
        object_shape=shaped,
        neighbours=neighbours,
        neighbour_start=start,
    )
