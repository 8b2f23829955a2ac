"""Figures of the hand law (optional: needs matplotlib, ``pip install openup-ompl[viz]``).

- :func:`plot_hand_law`: the paper's Fig. 3 for a plan: each hand joint against the
  normalised distance ``d`` and along the reach, with ``c``, ``b``, ``w`` and ``mga``.
- :func:`plot_law`: the law alone for several ``u`` (Fig. 3 of the paper for any ``u``).

Hand joints that share ``c``, ``b``, ``w`` (and values along the plan) share one row.
Prismatic joints are drawn in millimetres, revolute ones in degrees.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from openup_ompl.exceptions import ConfigError
from openup_ompl.hand_law import HandLaw
from openup_ompl.plan import Plan
from openup_ompl.viz._mpl import _pyplot, _save
from openup_ompl.viz._scene import PlanScene

#: Colours of the plan's states, the law curve, and the referential configurations.
STATE_COLOR = "#1f77b4"
LAW_COLOR = "#333333"
MGA_COLOR = "#d62728"


def figure_path(out: str | Path, where: str = "out") -> Path:
    """The file a figure saved to ``out`` lands in: ``out`` itself, or ``out.png`` for a
    name without a suffix (as matplotlib's ``savefig`` does), so that callers report the
    real path.

    Args:
        out: The file asked for.
        where: How to name it in an error.

    Returns:
        The path the figure will be written to.

    Raises:
        ConfigError: ``out`` is a directory, or its suffix a format matplotlib cannot
            write (the message lists those it can), named at ``where``.
        MissingExtra: matplotlib is not installed.
    """
    path = Path(out)
    if path.is_dir():
        raise ConfigError(where, str(path), "an image file to write (this is a directory)")
    if not path.suffix:
        path = path.with_name(f"{path.name}.png")
    _pyplot()
    from matplotlib.backend_bases import FigureCanvasBase

    formats = sorted(FigureCanvasBase.get_supported_filetypes())
    if path.suffix[1:].lower() not in formats:
        raise ConfigError(
            where, str(out), f"an image file ending in one of {', '.join('.' + f for f in formats)}"
        )
    return path


def _groups(columns: np.ndarray) -> list[list[int]]:
    """Indices of identical columns of ``columns`` (rows: c, b, w, then any values)."""
    groups: list[list[int]] = []
    for j in range(columns.shape[1]):
        for group in groups:
            if np.allclose(columns[:, group[0]], columns[:, j], atol=1e-12):
                group.append(j)
                break
        else:
            groups.append([j])
    return groups


def _scale(prismatic: bool) -> tuple[float, str]:
    return (1e3, "mm") if prismatic else (float(np.degrees(1.0)), "deg")


def _references(ax: Any, law: HandLaw, j: int, scale: float, inside: bool = False) -> None:
    """Dotted lines at c, b, w of joint ``j``, labelled at the right edge (``inside``:
    just above the line, inside the axes, leaving the edge to a twin axis). Levels closer
    than 4 % of the axis height share one label (``b = w`` when equal, else ``b, w``), so
    that labels never overlap."""
    levels = sorted((float(getattr(law, name)[j]) * scale, name) for name in ("c", "b", "w"))
    bottom, top = ax.get_ylim()
    near = 0.04 * abs(top - bottom)
    clusters: list[list[tuple[float, str]]] = []
    for value, name in levels:
        ax.axhline(value, ls=":", color="grey", lw=0.8, zorder=0)
        if clusters and value - clusters[-1][-1][0] <= near:
            clusters[-1].append((value, name))
        else:
            clusters.append([(value, name)])
    for cluster in clusters:
        values = [value for value, _ in cluster]
        equal = max(values) - min(values) <= 1e-9 * max(1.0, abs(max(values)))
        label = (" = " if equal else ", ").join(sorted(name for _, name in cluster))
        ax.annotate(
            label if inside else f" {label}",
            (0.995 if inside else 1.0, float(np.mean(values))),
            xycoords=("axes fraction", "data"),
            ha="right" if inside else "left",
            va="bottom" if inside else "center",
            fontsize=9,
            color="dimgrey",
        )


def _moving(law: HandLaw, groups: list[list[int]]) -> tuple[list[list[int]], list[list[int]]]:
    """``groups`` split into those the law moves and those it holds (``c = b = w``): a held
    joint gets no panel of its own, only a line under the figure. (If the law holds every
    joint, all are drawn.)"""
    held = [g for g in groups if np.ptp([law.c[g[0]], law.b[g[0]], law.w[g[0]]]) <= 1e-12]
    moving = [g for g in groups if g not in held]
    return (moving, held) if moving else (groups, [])


def _held_note(
    fig: Any, law: HandLaw, held: list[list[int]], names: Sequence[str], kinds: Any
) -> None:
    """A line under the figure naming the joints the law holds still, with their value."""
    if not held:
        return
    parts = []
    for group in held:
        scale, unit = _scale(bool(kinds[group[0]]))
        parts.append(f"{_joint_label(names, group)} at {float(law.c[group[0]]) * scale:g} {unit}")
    fig.text(
        0.5,
        0.005,
        "held still by the law (c = b = w): " + "; ".join(parts),
        ha="center",
        va="bottom",
        fontsize=8,
        color="dimgrey",
    )


def _mga_line(ax: Any, mga: float) -> None:
    ax.axvline(mga, ls="--", color=MGA_COLOR, lw=0.9, zorder=0)
    ax.annotate(
        "mga",
        (mga, 1.0),
        xycoords=("data", "axes fraction"),
        xytext=(2, -2),
        textcoords="offset points",
        va="top",
        fontsize=9,
        color=MGA_COLOR,
    )


def _law_curve(ax: Any, law: HandLaw, j: int, d_max: float, scale: float, **style: Any) -> Any:
    """Draw the law of joint ``j`` over ``[0, d_max]``, its two branches apart (the law
    as printed jumps at ``mga``)."""
    line = None
    for low, high, after in ((0.0, law.mga, 0.0), (law.mga, d_max, 1e-12)):
        if high > low:
            d = np.linspace(low, high, 100)
            line = ax.plot(d, law.batch(d + after)[:, j] * scale, **style)[0]
            style.pop("label", None)
    return line


def _padded_ylim(ax: Any, law: HandLaw, j: int, scale: float) -> None:
    values = np.array([law.c[j], law.b[j], law.w[j]]) * scale
    low, high = float(values.min()), float(values.max())
    bottom, top = ax.get_ylim()
    span = max(high - low, 1e-9)
    ax.set_ylim(min(bottom, low - 0.12 * span), max(top, high + 0.12 * span))


def _joint_label(names: Sequence[str], group: list[int]) -> str:
    if len(group) <= 2:
        return " = ".join(names[j] for j in group)
    return f"{names[group[0]]} (and {len(group) - 1} more)"


def _plan_scene(plan: str | Path | dict[str, Any] | Plan | PlanScene) -> PlanScene:
    if isinstance(plan, PlanScene):
        return plan
    if isinstance(plan, Plan):
        return PlanScene.from_plan(plan)
    if isinstance(plan, dict):
        return PlanScene.from_dict(plan)
    return PlanScene.from_file(plan)


def plot_hand_law(
    plan: str | Path | dict[str, Any] | Plan | PlanScene, out: str | Path, dpi: int = 130
) -> Path:
    """The paper's Fig. 3 for a plan: each hand joint against the normalised distance
    ``d`` (the law, and the plan's states on it) and along the reach (palm path length,
    normalised), with ``c``, ``b``, ``w``, ``mga`` and where the hand reached ``mga``.

    Args:
        plan: A plan file, its contents, a :class:`~openup_ompl.Plan`, or a loaded
            :class:`~openup_ompl.viz.PlanScene`.
        out: PNG file to write.
        dpi: Resolution [dot/inch].

    Returns:
        The PNG's path.

    Raises:
        MissingExtra: matplotlib is not installed.
        ConfigError: The plan file is not a readable plan; ``out`` a directory or in a
            format matplotlib cannot write (:func:`figure_path`).
    """
    path = figure_path(out)
    plt = _pyplot()
    scene = _plan_scene(plan)
    law, hand = scene.law, scene.hand_path
    groups, held = _moving(law, _groups(np.vstack([law.c, law.b, law.w, hand])))
    d_max = max(1.05, float(scene.distances.max()) * 1.02)
    mga_row = scene.mga_row
    fig, axes = plt.subplots(len(groups), 2, figsize=(11.5, 3.6 * len(groups) + 0.5), squeeze=False)
    for (left, right), group in zip(axes, groups, strict=True):
        j = group[0]
        scale, unit = _scale(bool(scene.prismatic[j]))
        _law_curve(
            left, law, j, d_max, scale, color=LAW_COLOR, lw=1.2, zorder=4, label="law (Alg. 3)"
        )
        left.scatter(
            scene.distances,
            hand[:, j] * scale,
            s=10,
            color=STATE_COLOR,
            alpha=0.35,
            lw=0,
            zorder=3,
            label=f"plan states ({len(hand)})",
        )
        right.plot(scene.progress, hand[:, j] * scale, color=STATE_COLOR, lw=1.6, label="hand")
        for ax in (left, right):
            _padded_ylim(ax, law, j, scale)
            _references(ax, law, j, scale, inside=ax is right)
            ax.set_ylabel(f"{_joint_label(scene.hand_joints, group)} [{unit}]", fontsize=9)
            ax.grid(alpha=0.25)
        _mga_line(left, law.mga)
        left.set_xlim(0.0, d_max)
        left.set_xlabel("normalised palm-to-grasp distance d")
        left.legend(fontsize=8, loc="lower right")
        twin = right.twinx()
        twin.plot(scene.progress, scene.distances, color="grey", lw=1.0, ls="--", label="d")
        twin.axhline(law.mga, color=MGA_COLOR, lw=0.6, ls=":")
        twin.set_ylabel("d", color="grey")
        twin.set_ylim(0.0, d_max)
        twin.tick_params(axis="y", colors="grey")
        if mga_row is not None:
            at = float(scene.progress[mga_row])
            right.axvline(at, ls="--", color=MGA_COLOR, lw=0.9)
            right.annotate(
                f"d = mga at {at:.0%}",
                (at, 0.02),
                xycoords=("data", "axes fraction"),
                xytext=(-3, 0),
                textcoords="offset points",
                ha="right",
                fontsize=9,
                color=MGA_COLOR,
            )
        right.set_xlim(0.0, 1.0)
        right.set_xlabel("reach progress (palm path length, normalised)")
        lines = right.get_lines()[:1] + twin.get_lines()[:1]
        right.legend(lines, [line.get_label() for line in lines], fontsize=8, loc="lower left")
    kind = " (fixed hand)" if law.fixed is not None else ""
    continuous = ", continuous" if law.continuous else ""
    continuous += ", open arrival" if law.open_arrival else ""
    axes[0, 0].set_title(
        f"Fig. 3 for this plan: hand law{kind}, u = {law.u:g}, mga = {law.mga:g}{continuous}"
    )
    axes[0, 1].set_title(f"{scene.plan.planner}: the hand along the reach")
    _held_note(fig, law, held, scene.hand_joints, scene.prismatic)
    fig.tight_layout(rect=(0.0, 0.025 if held else 0.0, 1.0, 1.0))
    return _save(fig, path, dpi)


def plot_law(
    law: HandLaw,
    out: str | Path,
    us: Sequence[float] = (0.0, 0.3, 1.0),
    joint_names: Sequence[str] | None = None,
    prismatic: Sequence[bool] | None = None,
    title: str | None = None,
    dpi: int = 130,
) -> Path:
    """The hand law alone for several ``u``: each hand joint against ``d`` (the paper's
    Fig. 3), with ``c``, ``b``, ``w`` and ``mga`` marked.

    Args:
        law: The law (``c``, ``b``, ``w``, ``mga``, limits); its ``u`` is replaced by each
            of ``us``.
        out: Image file to write (``.png`` added to a name without a suffix).
        us: Pose uncertainties to draw, each in [0, 1].
        joint_names: Hand joint names (default ``joint 0``, ``joint 1``, ...).
        prismatic: Per hand joint, whether it is prismatic (drawn in mm, else degrees);
            default all prismatic.
        title: Figure title.
        dpi: Resolution [dot/inch].

    Returns:
        The image's path.

    Raises:
        MissingExtra: matplotlib is not installed.
        ConfigError: No ``u`` given, or one outside [0, 1]; ``out`` a directory or
            in a format matplotlib cannot write (:func:`figure_path`).
    """
    if not us:
        raise ConfigError("u", list(us), "at least one u in [0, 1]")
    path = figure_path(out)
    laws = [law.with_options(u=float(u), fixed=None) for u in us]
    plt = _pyplot()
    names = list(joint_names or [f"joint {j}" for j in range(law.size)])
    kinds = list(prismatic) if prismatic is not None else [True] * law.size
    groups, held = _moving(law, _groups(np.vstack([law.c, law.b, law.w, law.lower, law.upper])))
    fig, axes = plt.subplots(len(groups), 1, figsize=(7.2, 3.9 * len(groups)), squeeze=False)
    colors = plt.get_cmap("viridis")(np.linspace(0.0, 0.85, len(laws)))
    for (ax,), group in zip(axes, groups, strict=True):
        j = group[0]
        scale, unit = _scale(bool(kinds[j]))
        for each, color in zip(laws, colors, strict=True):
            _law_curve(ax, each, j, 1.2, scale, color=color, lw=1.8, label=f"u = {each.u:g}")
        _padded_ylim(ax, law, j, scale)
        _references(ax, law, j, scale)
        _mga_line(ax, law.mga)
        ax.set_xlim(0.0, 1.2)
        ax.axvspan(1.0, 1.2, color="0.93", zorder=0)
        ax.annotate(
            "farther than\nat the start",
            (1.1, 0.03),
            xycoords=("data", "axes fraction"),
            ha="center",
            va="bottom",
            fontsize=8,
            color="grey",
        )
        ax.set_xlabel("normalised palm-to-grasp distance d (1 at the start, 0 at the grasp)")
        ax.set_ylabel(f"{_joint_label(names, group)} [{unit}]", fontsize=9)
        ax.grid(alpha=0.25)
        ax.legend(fontsize=8, loc="lower center")
    variant = ", continuous variant" if law.continuous else ""
    variant += ", open arrival" if law.open_arrival else ""
    axes[0, 0].set_title(title or f"hand law (Algorithm 3), mga = {law.mga:g}{variant}")
    _held_note(fig, law, held, names, kinds)
    fig.tight_layout(rect=(0.0, 0.03 if held else 0.0, 1.0, 1.0))
    return _save(fig, path, dpi)
