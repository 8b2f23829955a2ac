"""Pictures of a physics rollout (an ``execution.json`` written with its frames).

``show_execution`` writes the rollout as the plan viewer's HTML animation (the object
moving as it did) and a storyboard: one column per key instant (start, first touch,
end of the reach, hand closed, top of the lift, end of the hold), the scene above and a
close-up of the hand below, each titled with what happened there.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from openup_ompl.exceptions import ConfigError
from openup_ompl.plan import PlanFile
from openup_ompl.viz._scene import PlanScene

__all__ = ["ShownExecution", "key_frames", "show_execution", "write_rollout_storyboard"]


@dataclass(frozen=True)
class ShownExecution:
    """The files :func:`show_execution` wrote.

    Attributes:
        html: The rollout's interactive animation (one self-contained HTML file).
        storyboard: The reach / close / lift storyboard PNG.
    """

    html: Path
    storyboard: Path


def _loaded(execution: dict[str, Any], where: str = "") -> tuple[PlanScene, dict[str, Any]]:
    """The executed plan's scene and the frames of an execution file's contents (as
    :func:`~openup_ompl.physics.record.read_execution` checked them); ``where`` prefixes
    error locations (the file's name)."""
    frames, source = execution.get("frames"), execution.get("source")
    if not frames:
        raise ConfigError(
            f"{where}frames", None, "an execution.json written with its frames (execute)"
        )
    if not isinstance(source, dict):
        raise ConfigError(
            f"{where}source", source, "the executed plan file's contents (kept with the frames)"
        )
    plan = PlanFile.from_dict(source, "execution", where=f"{where}source.")
    if plan.object is None:  # the frames move an object: the storyboard draws it
        raise ConfigError(
            f"{where}source.scene.object", None, "the executed plan's object (a rollout moves one)"
        )
    names = source["robot"]["joint_names"]
    if frames["joint_names"] != names:
        raise ConfigError(
            f"{where}frames.joint_names", frames["joint_names"], f"{names} (source.robot's)"
        )
    return PlanScene.from_plan_file(plan), frames


def key_frames(execution: dict[str, Any]) -> list[tuple[int, str]]:
    """``(frame, title)`` of the instants the storyboard shows: the start, the first
    hand-object contact if it came before closing, the end of each of reach, close
    (with the squeeze), lift and hold.

    Args:
        execution: An execution file's contents (with frames).

    Returns:
        ``(frame index, panel title)`` pairs, in time order.
    """
    frames = execution["frames"]
    phases = frames["phase"]
    period = frames["period_s"]
    keys = [(0, "start")]
    first = execution.get("first_contact")
    if first and first["phase"] in ("settle", "reach"):
        k = min(len(phases) - 1, int(first["time_s"] / period))
        d = "?" if first.get("d") is None else f"{first['d']:.2f}"
        keys.append((k, f"touch: {first['link']}\nd = {d}"))
    for names, title in (
        (("reach",), "end of reach"),
        (("close", "squeeze"), "hand closed"),
        (("lift",), "top of lift"),
        (("hold",), "end of hold"),
    ):
        indices = [i for i, p in enumerate(phases) if p in names]
        if indices:
            keys.append((indices[-1], title))
    return keys


def write_rollout_storyboard(execution: dict[str, Any], out: str | Path, dpi: int = 110) -> Path:
    """Write the storyboard PNG of a rollout (module docstring) from an execution file's
    contents (:func:`~openup_ompl.physics.record.read_execution`).

    Args:
        execution: An execution file's contents (with frames).
        out: The PNG file.
        dpi: Resolution [dot/inch].

    Returns:
        The PNG's path.
    """
    scene, _ = _loaded(execution)
    return _storyboard(scene, execution, out, dpi)


def _storyboard(scene: PlanScene, execution: dict[str, Any], out: str | Path, dpi: int) -> Path:
    from openup_ompl.viz._geometry import placed, shape_mesh
    from openup_ompl.viz._mpl import _pyplot, _save
    from openup_ompl.viz.storyboard import (
        ARM_COLOR,
        HAND_COLOR,
        OBJECT_COLOR,
        OBSTACLE_COLOR,
        StoryboardOptions,
        _clipped,
        _draw,
        _Robot,
        _triangles,
        closeup_bounds,
    )

    plt = _pyplot()
    frames = execution["frames"]
    robot = _Robot(scene, StoryboardOptions())
    keys = key_frames(execution)
    q = np.asarray(frames["q"], dtype=float)
    poses = np.asarray(frames["object"], dtype=float)
    obstacles = [s for s in scene.shapes if s.name != scene.object_name]
    target = next(s for s in scene.shapes if s.name == scene.object_name)

    def environment(k: int, low: np.ndarray, high: np.ndarray) -> list[Any]:
        moved = dataclasses.replace(target, pose=poses[k])
        pushed = frames.get("neighbours") or {}  # movable obstacles' poses per frame
        shapes = [
            dataclasses.replace(s, pose=np.asarray(pushed[s.name][k])) if s.name in pushed else s
            for s in obstacles
        ]
        layers = []
        for shape in [*shapes, moved]:
            clipped = _clipped(shape, low, high)
            if clipped is not None:
                color = OBJECT_COLOR if shape is moved else OBSTACLE_COLOR
                mesh = shape_mesh(clipped, max_edge=0.04)
                layers.append((_triangles([placed(mesh, clipped.placement)]), color))
        return layers

    meshes = [robot.meshes_at(q[k]) for k, _ in keys]
    points = [v for arm, hand in meshes for v, _ in arm + hand]
    points.append(poses[:, :3])
    low = np.min([p.min(axis=0) for p in points], axis=0)
    high = np.max([p.max(axis=0) for p in points], axis=0)
    margin = 0.08 * float(np.max(high - low))
    low, high = low - margin, high + margin
    direction = scene.view_direction()
    size = 2.9
    fig = plt.figure(figsize=(size * len(keys), size * 1.9))
    grid = fig.add_gridspec(2, len(keys), height_ratios=[1.0, 0.9])
    grid.update(left=0.005, right=0.995, top=0.85, bottom=0.06, wspace=0.02, hspace=0.12)
    offset = execution["offset"]
    jitter = execution.get("jitter") or {"dx": 0.0, "dy": 0.0}
    shifted = (
        f" (+ jitter {jitter['dx'] * 100:.2g}, {jitter['dy'] * 100:.2g} cm)"
        if any(jitter.values())
        else ""
    )
    fig.suptitle(
        f"physics rollout, object offset dx = {offset['dx'] * 100:g} cm, dy ="
        f" {offset['dy'] * 100:g} cm, yaw = {np.degrees(offset['yaw']):.0f} deg{shifted}:"
        f" {execution['verdict']}",
        fontsize=12,
        y=0.99,
    )
    period = frames["period_s"]
    for column, ((k, title), (arm, hand)) in enumerate(zip(keys, meshes, strict=True)):
        ax = fig.add_subplot(grid[0, column], projection="3d")
        layers = [
            *environment(k, low, high),
            (_triangles(arm), ARM_COLOR),
            (_triangles(hand), HAND_COLOR),
        ]
        _draw(ax, layers, low, high, direction, zoom=1.35)
        ax.set_title(f"{title}\nt = {(k + 1) * period:.2f} s", fontsize=10.5, pad=0)
        arm, hand = robot.meshes_at(q[k], fine=True)
        if not hand:
            continue
        lo, hi = closeup_bounds(poses[k], hand, margin=1.3)
        close = fig.add_subplot(grid[1, column], projection="3d")
        layers = [
            *environment(k, lo, hi),
            (_triangles(arm), ARM_COLOR),
            (_triangles(hand), HAND_COLOR),
        ]
        _draw(close, layers, lo, hi, robot.closeup_direction(q[k], direction), strict=True)
    return _save(fig, out, dpi)


def show_execution(execution: str | Path, out_dir: str | Path | None = None) -> ShownExecution:
    """Write ``<stem>.html`` (the rollout animated) and ``<stem>_storyboard.png`` of an
    ``execution.json`` in ``out_dir`` (default: its directory).

    Args:
        execution: The ``execution.json`` file.
        out_dir: Where to write (default: the file's directory).

    Returns:
        The two paths written (:class:`ShownExecution`).

    Raises:
        ConfigError: Not an execution file, or one written without its frames.
        MissingExtra: matplotlib or meshcat is not installed.
    """
    from openup_ompl.physics.record import read_execution
    from openup_ompl.viz._mpl import _pyplot
    from openup_ompl.viz.html import Motion, _meshcat, write_html

    _pyplot()
    _meshcat()
    path = Path(execution)
    data = read_execution(path)
    scene, frames = _loaded(data, f"{path.name}: ")
    out = Path(out_dir) if out_dir is not None else path.parent
    period = float(frames["period_s"])
    labels = [f"{phase} {(k + 1) * period:5.2f} s" for k, phase in enumerate(frames["phase"])]
    motion = Motion(
        q=np.asarray(frames["q"], dtype=float),
        object_poses=np.asarray(frames["object"], dtype=float),
        labels=labels,
        fps=1.0 / period,
        details=data["verdict"],
    )
    board = _storyboard(scene, data, out / f"{path.stem}_storyboard.png", dpi=110)
    page = write_html(scene, out / f"{path.stem}.html", motion=motion)
    return ShownExecution(page, board)
