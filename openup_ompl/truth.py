"""A plan paired with the true object: after ``perceive`` -> ``plan``, the plan holds the
estimated object pose; its execution must meet the object where it really is
(``openup-ompl execute PLAN --truth SCENE.toml``, ``execute_plan(plan, truth=scene)``)."""

from __future__ import annotations

import dataclasses
from typing import overload

from openup_ompl.exceptions import ConfigError
from openup_ompl.plan import Plan, PlanFile
from openup_ompl.scene import Problem, Shape

__all__ = ["with_true_object"]


def _true_shape(plan: Plan | PlanFile, truth: Problem | Shape) -> Shape:
    """The object of ``truth``, a scene of the plan's robot or a shape."""
    if isinstance(truth, Problem):
        if isinstance(plan, Plan):
            planned = plan.problem.robot.spec.name
        else:
            planned = plan.contents.get("robot", {}).get("name")
        robot = truth.robot.spec.name
        if robot != planned:
            raise ConfigError("truth.robot", robot, f"the plan's robot {planned!r}")
        if truth.object is None:
            raise ConfigError("truth.object", None, "a true scene with an [object]")
        return truth.object
    if not isinstance(truth, Shape):
        raise ConfigError("truth", truth, "a scene (Problem) with an [object], or a Shape")
    return truth


@overload
def with_true_object(plan: Plan, truth: Problem | Shape) -> Plan: ...
@overload
def with_true_object(plan: PlanFile, truth: Problem | Shape) -> PlanFile: ...
def with_true_object(plan: Plan | PlanFile, truth: Problem | Shape) -> Plan | PlanFile:
    """The plan with its scene's object replaced by the true one (its shape, pose [world
    frame], mass and friction); the path, law and obstacles stay the plan's.

    Args:
        plan: A plan in memory or a plan file read.
        truth: The true scene (``load_scene`` of the scene the estimate came from) or its
            object.

    Returns:
        A copy of ``plan`` of the same kind; ``plan`` itself is unchanged.

    Raises:
        ConfigError: ``truth`` has no object, is neither a scene nor a shape, or its
            robot is not the plan's.
    """
    shape = _true_shape(plan, truth)
    if isinstance(plan, Plan):
        return dataclasses.replace(plan, problem=dataclasses.replace(plan.problem, object=shape))
    contents = dict(plan.contents)
    contents["scene"] = {**contents.get("scene", {}), "object": shape.to_table()}
    return dataclasses.replace(plan, object=shape, contents=contents)
