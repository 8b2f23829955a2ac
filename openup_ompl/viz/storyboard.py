"""A storyboard of a plan: frames of the reach side by side, rendered offscreen.

Top row: the whole scene at several instants of the reach (the palm's path drawn, the
travelled part solid). Bottom row: a close-up of the hand at the same instants, seen across
its opening direction, so that the fingers opening and closing with the law are visible.
Drawn with matplotlib's 3D axes (no display, no GPU): the robot's visual meshes, decimated
for the overview (matplotlib sorts a few ten thousand triangles per panel in well under a
second) and as loaded for the close-ups, where only the triangles near the hand are drawn.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from openup_ompl._toml import is_finite, is_integer
from openup_ompl.exceptions import ConfigError
from openup_ompl.scene import Shape
from openup_ompl.viz._geometry import Mesh, coal_mesh, decimate, placed, shape_mesh
from openup_ompl.viz._mpl import _pyplot, _save
from openup_ompl.viz._scene import PlanScene

ARM_COLOR = (0.80, 0.82, 0.86)
HAND_COLOR = (0.20, 0.42, 0.72)
OBJECT_COLOR = (0.93, 0.52, 0.13)
OBSTACLE_COLOR = (0.72, 0.66, 0.58)
PATH_COLOR = (0.12, 0.47, 0.71)
GRASP_COLOR = (0.84, 0.15, 0.16)


#: The most instants a storyboard shows (one panel each).
MAX_FRAMES = 24


@dataclass(frozen=True)
class StoryboardOptions:
    """How a storyboard is drawn.

    Attributes:
        frames: Number of instants shown, 2 to :data:`MAX_FRAMES` (the start and the
            grasp; from 3 on, the first instant at or below ``mga`` is among them).
        closeup: Add the row of hand close-ups.
        geometry: ``"visual"`` (the URDF's visual meshes, decimated to ``mesh_cell``) or
            ``"collision"`` (the collision geometry, as loaded).
        mesh_cell: Vertex-clustering cell of the visual meshes [m].
        panel_size: Width of one panel [inch].
        dpi: Resolution of the PNG [dot/inch], 1 to 1200.
    """

    frames: int = 6
    closeup: bool = True
    geometry: str = "visual"
    mesh_cell: float = 0.008
    panel_size: float = 2.9
    dpi: int = 110

    def __post_init__(self) -> None:
        if self.geometry not in ("visual", "collision"):
            raise ConfigError("storyboard geometry", self.geometry, "'visual' or 'collision'")
        if not (is_integer(self.frames) and 2 <= self.frames <= MAX_FRAMES):
            raise ConfigError("storyboard frames", self.frames, f"an integer in [2, {MAX_FRAMES}]")
        if not isinstance(self.closeup, bool):
            raise ConfigError("storyboard closeup", self.closeup, "true or false")
        for name in ("mesh_cell", "panel_size"):
            if not (is_finite(getattr(self, name)) and getattr(self, name) > 0):
                raise ConfigError(f"storyboard {name}", getattr(self, name), "a positive size")
        if not (is_integer(self.dpi) and 1 <= self.dpi <= 1200):
            raise ConfigError("storyboard dpi", self.dpi, "an integer in [1, 1200]")


def frame_rows(scene: PlanScene, count: int) -> list[int]:
    """Path rows to show: evenly spaced in palm travel, with the row where the hand
    reaches its maximum grip aperture (``d <= mga``) replacing the nearest of them.

    Args:
        scene: The loaded plan.
        count: How many frames (fewer than 2 count as 2).

    Returns:
        Row indices of the plan's path, increasing, the first 0 and the last the grasp.
    """
    count = max(2, count)
    targets = np.linspace(0.0, 1.0, count)
    rows = [int(np.argmin(np.abs(scene.progress - t))) for t in targets]
    mga = scene.mga_row
    # With only the two ends shown there is no inner frame to give to the mga row.
    if mga is not None and 0 < mga < len(scene.path) - 1 and mga not in rows and count > 2:
        inner = range(1, count - 1)
        nearest = min(inner, key=lambda i: abs(scene.progress[rows[i]] - scene.progress[mga]))
        rows[nearest] = mga
    rows[0], rows[-1] = 0, len(scene.path) - 1
    return sorted(set(rows))


class _Robot:
    """The robot's meshes (coarse for the overview, as loaded for close-ups), placed by
    forward kinematics."""

    def __init__(self, scene: PlanScene, options: StoryboardOptions) -> None:
        self.scene = scene
        visual = options.geometry == "visual"
        self.geometry = scene.geometry_model(pin.VISUAL if visual else pin.COLLISION)
        self.kinematics = scene.model.createData()
        self.placements = self.geometry.createData()
        self.fine = [coal_mesh(g.geometry, max_edge=0.04) for g in self.geometry.geometryObjects]
        self.coarse = self.fine
        if visual:
            self.coarse = [None if m is None else decimate(m, options.mesh_cell) for m in self.fine]
        self.is_hand = scene.hand_geometry(self.geometry)

    def placed_at(self, q: np.ndarray, fine: bool = False) -> list[Mesh | None]:
        """Per collision geometry, its world mesh at ``q`` (``None`` where it has none)."""
        pin.forwardKinematics(self.scene.model, self.kinematics, q)
        pin.updateGeometryPlacements(
            self.scene.model, self.kinematics, self.geometry, self.placements
        )
        return [
            None if mesh is None else placed(mesh, self.placements.oMg[i])
            for i, mesh in enumerate(self.fine if fine else self.coarse)
        ]

    def meshes_at(self, q: np.ndarray, fine: bool = False) -> tuple[list[Mesh], list[Mesh]]:
        """World meshes of the arm and of the hand (the links a hand joint moves) at ``q``."""
        arm: list[Mesh] = []
        hand: list[Mesh] = []
        for i, world in enumerate(self.placed_at(q, fine)):
            if world is not None:
                (hand if self.is_hand[i] else arm).append(world)
        return arm, hand

    def closeup_direction(self, q: np.ndarray, fallback: np.ndarray) -> np.ndarray:
        """A view direction across the finger gap at ``q``: perpendicular to the fingers'
        opening direction (their principal motion from ``c`` to ``w``) and to the
        approach (palm origin to fingers), on the side of ``fallback``."""
        centres = []
        for hand in (self.scene.law.c, self.scene.law.w):
            q = q.copy()
            q[self.scene.hand_idx] = hand
            _, meshes = self.meshes_at(q)
            centres.append(np.array([m[0].mean(axis=0) for m in meshes]).reshape(-1, 3))
        moves = centres[1] - centres[0]
        if not moves.size or np.max(np.linalg.norm(moves, axis=1)) < 1e-9:
            return fallback
        opening = np.linalg.svd(moves)[2][0]
        pin.framesForwardKinematics(self.scene.model, self.kinematics, q)
        approach = (
            centres[0].mean(axis=0) - self.kinematics.oMf[self.scene.palm_frame_id].translation
        )
        direction = np.cross(opening, approach)
        if np.linalg.norm(direction) < 1e-9:
            direction = fallback - (fallback @ opening) * opening
        direction /= np.linalg.norm(direction)
        return direction if direction @ fallback >= 0 else -direction


def _clipped(shape: Shape, low: np.ndarray, high: np.ndarray) -> Shape | None:
    """A world-axis-aligned box cut to ``[low, high]`` (``None`` if outside); any other
    shape unchanged."""
    rotation = shape.placement.rotation
    if shape.shape != "box" or not np.allclose(np.abs(rotation).max(axis=0), 1.0):
        return shape
    assert shape.size is not None
    centre = shape.placement.translation
    half = np.abs(rotation) @ (shape.size / 2)
    lo, hi = np.maximum(centre - half, low), np.minimum(centre + half, high)
    if np.any(hi <= lo):
        return None
    pose = np.concatenate([(lo + hi) / 2, [0.0, 0.0, 0.0, 1.0]])
    return Shape(shape.name, "box", pose, size=hi - lo)


def _triangles(meshes: list[Mesh]) -> np.ndarray:
    if not meshes:
        return np.zeros((0, 3, 3))
    return np.concatenate([v[f] for v, f in meshes])


def _shaded(triangles: np.ndarray, color: tuple[float, ...], light: np.ndarray) -> np.ndarray:
    """Per-triangle RGB: a two-sided Lambert term (mesh windings are not trusted)."""
    normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    lambert = np.abs(normals @ light)
    shade = 0.45 + 0.55 * lambert
    return np.clip(np.asarray(color)[None, :] * shade[:, None], 0.0, 1.0)


def _view_angles(direction: np.ndarray) -> tuple[float, float]:
    """matplotlib ``(elev, azim)`` [deg] of a camera in ``direction`` from the scene."""
    d = direction / np.linalg.norm(direction)
    return float(np.degrees(np.arcsin(d[2]))), float(np.degrees(np.arctan2(d[1], d[0])))


def _draw(
    ax: Any,
    layers: list[tuple[np.ndarray, tuple[float, ...]]],
    low: np.ndarray,
    high: np.ndarray,
    direction: np.ndarray,
    zoom: float = 1.0,
    strict: bool = False,
) -> None:
    """Draw shaded triangles inside the box ``[low, high]`` (world frame, metres) seen
    from ``direction``; triangles whose centre (``strict``: any vertex) is outside the box
    are left out."""
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    light = direction + np.array([0.3, 0.3, 0.6])
    light /= np.linalg.norm(light)
    triangles, colors = [], []
    for tris, color in layers:
        margin = 0.02 * (high - low)
        if strict:
            inside = np.all((tris >= low - margin) & (tris <= high + margin), axis=(1, 2))
        else:
            centres = tris.mean(axis=1)
            inside = np.all((centres >= low - margin) & (centres <= high + margin), axis=1)
        triangles.append(tris[inside])
        colors.append(_shaded(tris[inside], color, light))
    polys = Poly3DCollection(
        np.concatenate(triangles),
        facecolors=np.concatenate(colors),
        edgecolors=np.concatenate(colors),
        linewidths=0.15,
        zorder=1,
    )
    ax.add_collection3d(polys)
    ax.set_xlim(low[0], high[0])
    ax.set_ylim(low[1], high[1])
    ax.set_zlim(low[2], high[2])
    ax.set_box_aspect(tuple(high - low), zoom=zoom)
    ax.set_proj_type("ortho")
    elev, azim = _view_angles(direction)
    ax.view_init(elev=elev, azim=azim)
    ax.set_axis_off()
    ax.computed_zorder = False


def closeup_bounds(
    anchor: np.ndarray, hand: list[Mesh], margin: float
) -> tuple[np.ndarray, np.ndarray]:
    """The cube [m, world frame] a hand close-up draws: around ``anchor`` (a position, or a
    pose whose first three values are one: the palm's origin, the object's centre) and the
    hand's triangles, its side ``margin`` times their largest extent.

    Args:
        anchor: A position [m] or a pose whose first three values are one.
        hand: The hand's meshes (vertices [m], triangles).
        margin: The cube's side over the hand's largest extent.

    Returns:
        ``(low, high)`` corners [m], each ``(3,)``.
    """
    points = np.concatenate(
        [np.asarray(anchor, dtype=float)[None, :3], _triangles(hand).reshape(-1, 3)]
    )
    lo, hi = points.min(axis=0), points.max(axis=0)
    middle, half = (lo + hi) / 2, float(np.max(hi - lo)) / 2 * margin
    return middle - half, middle + half


def _environment(
    scene: PlanScene, low: np.ndarray, high: np.ndarray
) -> list[tuple[np.ndarray, tuple[float, ...]]]:
    """Triangles and colours of the obstacles and the object, boxes cut to the view."""
    layers: list[tuple[np.ndarray, tuple[float, ...]]] = []
    for shape in scene.shapes:
        clipped = _clipped(shape, low, high)
        if clipped is not None:
            color = OBJECT_COLOR if shape.name == scene.object_name else OBSTACLE_COLOR
            mesh = shape_mesh(clipped, max_edge=0.04)
            layers.append((_triangles([placed(mesh, clipped.placement)]), color))
    return layers


def _title(scene: PlanScene, row: int) -> str:
    if row == 0:
        title = "start"
    elif row == len(scene.path) - 1:
        title = "grasp"
    elif row == scene.mga_row:
        title = f"MGA, {scene.progress[row]:.0%} of the reach"
    else:
        title = f"{scene.progress[row]:.0%} of the reach"
    d = float(scene.distances[row])
    return f"{title}\nd = {d:.2f}" + (", farther than at the start" if d > 1.005 else "")


def write_storyboard(
    scene: PlanScene, out: str | Path, options: StoryboardOptions | None = None
) -> Path:
    """Write the storyboard PNG of a plan.

    Args:
        scene: The plan, loaded (:meth:`PlanScene.from_file`).
        out: PNG file to write.
        options: Number of frames, geometry, size, resolution.

    Returns:
        The PNG's path.
    """

    plt = _pyplot()
    options = options or StoryboardOptions()
    robot = _Robot(scene, options)
    rows = frame_rows(scene, options.frames)
    frames = [robot.meshes_at(scene.path[row]) for row in rows]

    # The overview frames the robot over the shown instants and the object; obstacles
    # larger than that are cut to it (axis-aligned boxes exactly, others by triangles).
    points = [v for arm, hand in frames for v, _ in arm + hand]
    small = [s for s in scene.shapes if s.name == scene.object_name]
    points += [placed(shape_mesh(s), s.placement)[0] for s in small]
    low = np.min([p.min(axis=0) for p in points], axis=0)
    high = np.max([p.max(axis=0) for p in points], axis=0)
    margin = 0.08 * float(np.max(high - low))
    low, high = low - margin, high + margin
    environment = _environment(scene, low, high)
    direction = scene.view_direction()

    n_rows = 2 if options.closeup else 1
    size = options.panel_size
    fig = plt.figure(figsize=(size * len(rows), size * (1.0 if n_rows == 1 else 1.9)))
    grid = fig.add_gridspec(n_rows, len(rows), height_ratios=[1.0, 0.9][:n_rows])
    grid.update(left=0.005, right=0.995, top=0.82, bottom=0.06, wspace=0.02, hspace=0.12)
    law = scene.law
    fig.suptitle(
        f"{scene.plan.planner} reach to grasp, the hand following the law"
        f" (u = {law.u:g}, mga = {law.mga:g})" + ("" if law.fixed is None else " — fixed hand"),
        fontsize=14,
        y=0.99,
    )
    fig.text(
        0.5,
        0.935,
        "d: the palm's distance to the grasp over its distance at the start (Algorithm 1),"
        " above 1 where the palm first moves away; the hand follows the law of d"
        " (Algorithm 3), widest where d reaches mga",
        ha="center",
        fontsize=10,
        color="dimgrey",
    )
    for column, (row, (arm, hand)) in enumerate(zip(rows, frames, strict=True)):
        ax = fig.add_subplot(grid[0, column], projection="3d")
        layers = [*environment, (_triangles(arm), ARM_COLOR), (_triangles(hand), HAND_COLOR)]
        _draw(ax, layers, low, high, direction, zoom=1.35)
        ax.plot(*scene.palm.T, color=PATH_COLOR, lw=0.8, ls=":", alpha=0.8, zorder=2)
        ax.plot(*scene.palm[: row + 1].T, color=PATH_COLOR, lw=1.6, zorder=3)
        ax.scatter(*scene.grasp.translation, color=GRASP_COLOR, marker="x", s=28, zorder=4)
        ax.set_title(_title(scene, row), fontsize=11, pad=0)
        if not options.closeup:
            continue
        q = scene.path[row]
        arm, hand = robot.meshes_at(q, fine=True)
        if not hand:
            continue
        lo, hi = closeup_bounds(scene.palm[row], hand, margin=1.5)
        close = fig.add_subplot(grid[1, column], projection="3d")
        layers = [
            *_environment(scene, lo, hi),
            (_triangles(arm), ARM_COLOR),
            (_triangles(hand), HAND_COLOR),
        ]
        _draw(close, layers, lo, hi, robot.closeup_direction(q, direction), strict=True)
        values = scene.hand_path[row]
        share = float(scene.opening(values)[0])
        past = "; past w: the law's jump at mga" if share > 1.005 else ""
        close.set_title(
            f"hand {share:.0%} of the way c → w\n{scene.hand_text(values)}{past}",
            fontsize=10.5,
            y=-0.1,
        )
    return _save(fig, out, options.dpi)
