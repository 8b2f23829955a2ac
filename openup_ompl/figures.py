"""Figures of a plan (optional: needs matplotlib, ``pip install openup-ompl[viz]``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from openup_ompl.exceptions import OpenUpError
from openup_ompl.plan import Plan


class MissingExtra(OpenUpError, ImportError):
    """An optional dependency is not installed."""

    def __init__(self, module: str, extra: str) -> None:
        self.module = module
        self.extra = extra
        super().__init__(f"{module} is needed for this: pip install 'openup-ompl[{extra}]'")


def _pyplot() -> Any:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise MissingExtra("matplotlib", "viz") from None
    return plt


def plot_hand_law(plan: Plan, distances: np.ndarray, out: str | Path) -> Path:
    """The paper's Fig. 3 for a plan: each hand joint against the normalised distance
    ``d`` and against path progress, with ``c``, ``b``, ``w`` and ``mga`` marked.

    Args:
        plan: The plan.
        distances: ``d`` at every row of ``plan.path``.
        out: PNG file to write.
    """
    plt = _pyplot()
    law = plan.law
    hand = plan.hand_path
    names = plan.problem.robot.spec.hand_joints
    arm = plan.arm_path
    progress = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(arm, axis=0), axis=1))])
    progress /= max(progress[-1], 1e-12)
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.2))
    grid = np.linspace(0.0, max(1.2, float(distances.max())), 400)
    curve = law.batch(grid)
    for j, name in enumerate(names):
        line = left.plot(grid, curve[:, j], lw=1, alpha=0.6)[0]
        left.scatter(distances, hand[:, j], s=6, color=line.get_color(), label=name)
        right.plot(progress, hand[:, j], color=line.get_color(), label=name)
    for value, label in ((law.c, "c"), (law.b, "b"), (law.w, "w")):
        for axis in (left, right):
            axis.axhline(float(np.mean(value)), ls=":", color="grey", lw=0.8)
            axis.text(
                axis.get_xlim()[1], float(np.mean(value)), f" {label}", va="center", fontsize=8
            )
    left.axvline(law.mga, ls="--", color="k", lw=0.8)
    left.text(law.mga, left.get_ylim()[1], " mga", va="top", fontsize=8)
    left.set_xlabel("normalised palm-to-grasp distance d")
    left.set_ylabel("hand joint value [rad or m]")
    left.set_title(f"hand law, u = {law.u:g}" + (" (fixed hand)" if law.fixed is not None else ""))
    right.set_xlabel("path progress (arm joint-space arc length, normalised)")
    right.set_title(f"{plan.planner}: hand along the reach")
    left.legend(fontsize=7, loc="best")
    fig.tight_layout()
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out
