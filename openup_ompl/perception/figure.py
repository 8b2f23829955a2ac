"""The perception figure: the cloud, the fitted superquadric, the true object and the
2-sigma ellipse of the estimated position (needs the ``viz`` extra, matplotlib)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from openup_ompl._io import make_dir
from openup_ompl.perception.nominal import nominal_of
from openup_ompl.perception.perceive import Perception
from openup_ompl.perception.superquadric import Superquadric
from openup_ompl.scene import Shape

__all__ = ["ELLIPSE_CHI2", "plot_closed_loop", "plot_perception", "shape_superquadric"]

#: The "2-sigma" ellipse in a plane: Mahalanobis radius^2 of chi^2 with 2 dof at 95.45 %,
#: the probability of +-2 sigma in one dimension (a 2D ellipse at radius 2 holds 86.5 %).
ELLIPSE_CHI2 = 6.18


def shape_superquadric(shape: Shape) -> Superquadric:
    """A scene shape as a near-exact superquadric (exponents 0.02 for edges), to draw.

    Args:
        shape: A box, cylinder or sphere of a scene.

    Returns:
        The superquadric (half-sizes [m], exponents, pose).
    """
    placement = pin.XYZQUATToSE3(shape.pose)
    if shape.shape == "box":
        assert shape.size is not None
        sizes, exponents = np.asarray(shape.size) / 2, np.array([0.02, 0.02])
    elif shape.shape == "cylinder":
        assert shape.radius is not None and shape.length is not None
        sizes = np.array([shape.radius, shape.radius, shape.length / 2])
        exponents = np.array([0.02, 1.0])
    elif shape.shape == "sphere":
        assert shape.radius is not None
        sizes, exponents = np.full(3, shape.radius), np.ones(2)
    else:  # a mesh: its bounding box, rounded
        nominal = nominal_of(shape)
        sizes, exponents = nominal.half, np.array([0.5, 0.5])
        placement = placement * pin.SE3(np.eye(3), nominal.centre)
    return Superquadric(sizes, exponents, placement.translation.copy(), placement.rotation.copy())


def _ellipse(centre: np.ndarray, covariance: np.ndarray, chi2: float) -> np.ndarray:
    values, vectors = np.linalg.eigh(covariance)
    angle = np.linspace(0, 2 * np.pi, 100)
    circle = np.stack([np.cos(angle), np.sin(angle)])
    return (vectors @ (np.sqrt(np.maximum(values, 0) * chi2)[:, None] * circle)).T + centre


def plot_perception(perception: Perception, truth: Shape, out: Path, title: str = "") -> Path:
    """Draw ``perception`` against the true object into ``out`` (PNG).

    Left: the object's points, the fitted superquadric (wireframe) and the true object
    (grey) in 3D. Right: the same from above (world x-y) with the estimated centre's
    2-sigma ellipse (:data:`ELLIPSE_CHI2`) and the true centre.

    Args:
        perception: The perception (cloud, fit, covariance, ``u``).
        truth: The true object.
        out: The PNG file (its directory is created).
        title: Figure title (default: ``u`` and the point count).

    Returns:
        ``out``.

    Raises:
        MissingExtra: matplotlib is not installed.
    """
    from openup_ompl.viz._mpl import _pyplot

    plt = _pyplot()
    fig = plt.figure(figsize=(11, 5))
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    points = perception.cloud.points
    fitted = perception.fit.superquadric.surface(20)
    true = shape_superquadric(truth).surface(20)
    ax.scatter(*points.T, s=2, c="tab:blue", label="object points")
    ax.plot_wireframe(
        *np.moveaxis(fitted, -1, 0), color="tab:orange", lw=0.6, rstride=3, cstride=4, label="fit"
    )
    ax.plot_wireframe(
        *np.moveaxis(true, -1, 0), color="k", lw=0.4, rstride=3, cstride=4, label="true object"
    )
    low, high = true.reshape(-1, 3).min(0), true.reshape(-1, 3).max(0)
    middle, span = (low + high) / 2, float(np.max(high - low)) * 0.75
    for setter, m in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), middle, strict=True):
        setter(m - span, m + span)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    ax.legend(loc="upper left", fontsize=8)
    top = fig.add_subplot(1, 2, 2)
    top.scatter(points[:, 0], points[:, 1], s=2, c="tab:blue")
    outline = _ellipse(truth.pose[:2], np.eye(2), 1.0)
    if truth.shape in ("cylinder", "sphere"):
        assert truth.radius is not None
        top.plot(
            *(truth.pose[:2] + (outline - truth.pose[:2]) * truth.radius).T,
            "k",
            lw=0.8,
            label="true object (top view)",
        )
    fitted_top = fitted[fitted.shape[0] // 2]  # the equator of the fit
    top.plot(fitted_top[:, 0], fitted_top[:, 1], color="tab:orange", lw=0.8, label="fit")
    estimate = perception.pose[:3]
    ellipse = _ellipse(estimate[:2], perception.position_covariance[:2, :2], ELLIPSE_CHI2)
    top.plot(*ellipse.T, color="tab:red", label="2-sigma ellipse (95 %)")
    top.plot(*estimate[:2], "+", color="tab:orange", ms=10, label="estimated centre")
    top.plot(*truth.pose[:2], "x", color="k", ms=8, label="true centre")
    top.set_aspect("equal")
    top.set_xlabel("x [m]")
    top.set_ylabel("y [m]")
    top.legend(fontsize=8)
    fig.suptitle(title or f"u = {perception.u:.3f}, {perception.fit.points} points")
    fig.tight_layout()
    make_dir(out.parent)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def plot_closed_loop(rows: Sequence[dict[str, Any]], out: Path, title: str = "") -> Path:
    """Success rate against the sensor noise scale, one line per policy, one panel per
    camera distance, with Wilson 95 % intervals and the trial count of each point.

    Args:
        rows: The rows of :func:`~openup_ompl.perception.closed_loop.summarize` (or of
            ``closed_loop.csv``): ``policy``, ``noise``, ``distance`` [m], ``trials``,
            ``successes``.
        out: PNG file to write (its directory is created).
        title: Figure title, wrapped to the figure's width (default: none).

    Returns:
        The PNG's path.

    Raises:
        MissingExtra: matplotlib is not installed.
    """
    import textwrap

    from scipy.stats import binomtest

    from openup_ompl.viz._mpl import _pyplot

    plt = _pyplot()
    distances = sorted({row["distance"] for row in rows})
    policies = list(dict.fromkeys(row["policy"] for row in rows))
    noises = sorted({row["noise"] for row in rows})
    width = 4.5 * len(distances)
    fig, axes = plt.subplots(1, len(distances), figsize=(width, 3.8), sharey=True)
    # Policies side by side around each noise, so that equal rates do not hide each other.
    dodge = 0.012 * (max(noises) - min(noises) or 1.0)
    for ax, distance in zip(np.atleast_1d(axes), distances, strict=True):
        counts: set[int] = set()
        for k, policy in enumerate(policies):
            cells = sorted(
                (row["noise"], int(row["successes"]), int(row["trials"]))
                for row in rows
                if row["distance"] == distance and row["policy"] == policy
            )
            if not cells:
                continue
            x = np.array([c[0] for c in cells]) + (k - (len(policies) - 1) / 2) * dodge
            rate = np.array([c[1] / c[2] for c in cells])
            ci = [binomtest(c[1], c[2]).proportion_ci(method="wilson") for c in cells]
            low = rate - np.array([interval.low for interval in ci])
            high = np.array([interval.high for interval in ci]) - rate
            label = "u from covariance" if policy == "covariance" else f"u = {policy}"
            ax.errorbar(x, rate, yerr=[low, high], fmt="o-", capsize=2, lw=1.2, label=label)
            counts.update(c[2] for c in cells)
        shown = "/".join(str(n) for n in sorted(counts))
        ax.set_title(f"camera at {distance:g} m, {shown} trials per point", fontsize=10)
        ax.set_xlabel("sensor noise scale (1: Kinect v1)")
        ax.set_ylim(-0.05, 1.05)
        ax.grid(alpha=0.3)
    first = np.atleast_1d(axes)[0]
    first.set_ylabel("success rate (Wilson 95 % interval)")
    first.legend(fontsize=8)
    if title:
        fig.suptitle(textwrap.fill(title, width=int(width * 11)), fontsize=11)
    fig.tight_layout()
    make_dir(out.parent)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out
