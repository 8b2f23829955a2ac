"""The paper's Fig. 1 for one plan: its grasp executed against displaced objects.

One column per object pose error: on top the hand as the plan leaves it at the grasp (the
law's opening), the true object where it is; below, the hand after closing the fingers,
coloured by the trial's outcome, with the outcome in the title.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from openup_ompl.plan import Plan
from openup_ompl.scene import Shape
from openup_ompl.viz._mpl import _pyplot, _save
from openup_ompl.viz._scene import PlanScene
from openup_ompl.viz.storyboard import (
    ARM_COLOR,
    HAND_COLOR,
    StoryboardOptions,
    _draw,
    _environment,
    _Robot,
    _triangles,
)

SUCCESS_COLOR = (0.18, 0.62, 0.30)
FAILURE_COLOR = (0.80, 0.18, 0.16)


def _label(dx: float, dy: float, yaw: float) -> str:
    parts = [f"{name} {value * 100:+g} cm" for name, value in (("x", dx), ("y", dy)) if value]
    if yaw:
        parts.append(f"yaw {yaw:+g} rad")
    return ", ".join(parts) or "nominal pose"


def _outcome(trial: dict[str, object]) -> str:
    if trial["collision"]:
        pairs = trial["pairs"]
        link = str(pairs[0][0]).removesuffix("_0") if isinstance(pairs, list) and pairs else ""
        return f"touches the object on the way in\n{link}"
    return "force closure" if trial["force_closure"] else "no force closure"


def write_grasp_figure(
    plan: Plan,
    columns: Sequence[tuple[dict[str, object], np.ndarray, Shape]],
    out: str | Path,
    *,
    options: StoryboardOptions | None = None,
) -> Path:
    """Draw one plan's grasp against displaced objects, one column per executed trial.

    Args:
        plan: The plan (its last row is the open hand at the grasp).
        columns: Per trial ``(trial, closed q, true object)``: the trial record (``dx,
            dy, yaw, collision, pairs, force_closure, success``), the full configuration
            after closing the hand, and the object where it really was (world frame), as
            :func:`openup_ompl.robustness.figure_trials` gives them.
        out: The PNG to write.
        options: Rendering settings.

    Returns:
        The PNG's path.

    Raises:
        MissingExtra: matplotlib is not installed.
    """
    plt = _pyplot()
    options = options or StoryboardOptions()
    scene = PlanScene.from_plan(plan, "grasps")
    robot = _Robot(scene, options)
    last = plan.path[-1]
    size = options.panel_size
    fig = plt.figure(figsize=(size * len(columns), size * 2.15))
    grid = fig.add_gridspec(2, len(columns))
    grid.update(left=0.005, right=0.995, top=0.86, bottom=0.02, wspace=0.02, hspace=0.25)
    variant = ", open arrival" if plan.law.open_arrival else ""
    fig.suptitle(
        f"{plan.planner} plan at the nominal pose (u = {plan.law.u:g}{variant}), executed"
        " against the true object: open (top) and closed (bottom)",
        fontsize=13,
        y=0.99,
    )
    arm, open_hand = robot.meshes_at(last, fine=True)
    points = _triangles(open_hand).reshape(-1, 3)
    middle = (points.min(axis=0) + points.max(axis=0)) / 2
    half = float(np.max(points.max(axis=0) - points.min(axis=0))) / 2 * 1.45
    low, high = middle - half, middle + half
    direction = robot.closeup_direction(last, scene.view_direction())
    for column, (trial, closed_q, true_object) in enumerate(columns):
        dx, dy, yaw = (float(trial[key]) for key in ("dx", "dy", "yaw"))  # type: ignore[arg-type]
        shapes = [s for s in scene.shapes if s.name != scene.object_name] + [true_object]
        moved = dataclasses.replace(scene, shapes=shapes)
        environment = _environment(moved, low, high)
        top = fig.add_subplot(grid[0, column], projection="3d")
        layers = [*environment, (_triangles(arm), ARM_COLOR), (_triangles(open_hand), HAND_COLOR)]
        _draw(top, layers, low, high, direction, strict=True)
        top.set_title(_label(dx, dy, yaw), fontsize=11, pad=0)
        _, closed = robot.meshes_at(closed_q, fine=True)
        colour = SUCCESS_COLOR if trial["success"] else FAILURE_COLOR
        bottom = fig.add_subplot(grid[1, column], projection="3d")
        layers = [*environment, (_triangles(arm), ARM_COLOR), (_triangles(closed), colour)]
        _draw(bottom, layers, low, high, direction, strict=True)
        bottom.set_title(_outcome(trial), fontsize=10, pad=0, color=colour)
    return _save(fig, out, options.dpi)
