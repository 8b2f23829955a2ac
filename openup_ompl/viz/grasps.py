"""The paper's Fig. 1 for one plan: its grasp executed against displaced objects.

One column per object pose error: on top the hand as the plan leaves it at the grasp (the
law's opening), the true object where it is; below, the hand after closing the fingers,
coloured by the trial's outcome, with the outcome in the title.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

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

if TYPE_CHECKING:
    from openup_ompl.plan import Plan
    from openup_ompl.planning import GraspPlanningSetup

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
    setup: GraspPlanningSetup,
    plan: Plan,
    cells: Sequence[tuple[float, float, float]],
    out: str | Path,
    *,
    friction: float = 0.5,
    torsion: float = 0.0,
    options: StoryboardOptions | None = None,
) -> Path:
    """Write the figure for ``plan`` (made by ``setup``) and the errors ``cells``
    (``(dx, dy, yaw)`` [m, m, rad], world frame).

    Returns:
        The PNG's path.

    Raises:
        MissingExtra: matplotlib is not installed.
    """
    from openup_ompl.robustness import displaced, execute

    plt = _pyplot()
    options = options or StoryboardOptions()
    scene = PlanScene.from_dict(plan.to_dict(), "grasps")
    robot = _Robot(scene, options)
    last = plan.path[-1]
    size = options.panel_size
    fig = plt.figure(figsize=(size * len(cells), size * 2.15))
    grid = fig.add_gridspec(2, len(cells))
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
    for column, (dx, dy, yaw) in enumerate(cells):
        trial, grasp = execute(setup, plan, dx, dy, yaw, friction=friction, torsion=torsion)
        true = displaced(setup.problem, dx, dy, yaw)
        assert true.object is not None
        shapes = [s for s in scene.shapes if s.name != scene.object_name] + [true.object]
        moved = dataclasses.replace(scene, shapes=shapes)
        environment = _environment(moved, low, high)
        top = fig.add_subplot(grid[0, column], projection="3d")
        layers = [*environment, (_triangles(arm), ARM_COLOR), (_triangles(open_hand), HAND_COLOR)]
        _draw(top, layers, low, high, direction, strict=True)
        top.set_title(_label(dx, dy, yaw), fontsize=11, pad=0)
        _, closed = robot.meshes_at(grasp.q, fine=True)
        colour = SUCCESS_COLOR if trial["success"] else FAILURE_COLOR
        bottom = fig.add_subplot(grid[1, column], projection="3d")
        layers = [*environment, (_triangles(arm), ARM_COLOR), (_triangles(closed), colour)]
        _draw(bottom, layers, low, high, direction, strict=True)
        bottom.set_title(_outcome(trial), fontsize=10, pad=0, color=colour)
    return _save(fig, out, options.dpi)
