"""How well the reported covariance holds: the share of views whose true object position
lies inside the reported 95 % region, per shape and sensor noise.

The objects stand where the shipped LWA3 scene's can stands (``scenes/lwa3_sdh_can.toml``)
and are seen through its camera: the can itself (``cylinder``), a 50 x 80 x 120 mm box, a
40 mm ball, a 30 cm stick of 15 mm radius and the shipped bottle mesh
(``scenes/meshes/bottle.obj``). Each view is perceived with its own seed; its Mahalanobis
distance ``d^2 = e^T Sigma^-1 e`` of the position error ``e`` under the reported position
covariance ``Sigma`` is kept, so that the coverage at any level ``p`` is the share of
views with ``d^2`` under the chi-square (3 dof) quantile of ``p`` (95 %: 7.81). The
views refused (a :class:`~openup_ompl.exceptions.PerceptionError`) are counted apart.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from openup_ompl.exceptions import ConfigError, PerceptionError
from openup_ompl.perception.camera import DepthCamera, camera_of_scene
from openup_ompl.perception.extrinsic import PerceptionOptions
from openup_ompl.perception.noise import NoiseOptions
from openup_ompl.perception.perceive import perceive
from openup_ompl.scene import Problem, Shape, load_scene

__all__ = [
    "CALIBRATION_SHAPES",
    "Coverage",
    "calibration_scene",
    "coverage",
    "coverage_table",
    "wilson_interval",
]

ROOT = Path(__file__).resolve().parents[2]
#: The objects calibrated: ``name -> (Shape fields, height of its centre [m])``.
CALIBRATION_SHAPES: dict[str, tuple[dict[str, Any], float]] = {
    "cylinder": ({"shape": "cylinder", "radius": 0.033, "length": 0.16}, 0.08),
    "box": ({"shape": "box", "size": np.array([0.05, 0.08, 0.12])}, 0.06),
    "sphere": ({"shape": "sphere", "radius": 0.04}, 0.04),
    "stick": ({"shape": "cylinder", "radius": 0.015, "length": 0.30}, 0.15),
    "mesh": (
        {"shape": "mesh", "file": ROOT / "scenes" / "meshes" / "bottle.obj", "scale": 1.0},
        0.1,
    ),
}
#: The seed offset between noise levels (:func:`coverage_table`).
SEED_STRIDE = 100_000
#: The chi-square (3 dof) quantile of 95 %: the reported 95 % region of the position.
CHI2_3_95 = 7.815


def calibration_scene(name: str) -> Problem:
    """The LWA3 can scene with its object swapped for :data:`CALIBRATION_SHAPES`
    ``name``, standing where the can stands.

    Args:
        name: A key of :data:`CALIBRATION_SHAPES`.

    Returns:
        The scene, its object the named shape.

    Raises:
        ConfigError: An unknown name.
    """
    if name not in CALIBRATION_SHAPES:
        raise ConfigError("shape", name, f"one of {sorted(CALIBRATION_SHAPES)}")
    problem = load_scene(ROOT / "scenes" / "lwa3_sdh_can.toml")
    assert problem.object is not None
    fields, height = CALIBRATION_SHAPES[name]
    pose = problem.object.pose.copy()
    pose[2] = height
    shape = Shape(f"calibration_{name}", pose=pose, mass=0.1, **fields)
    return dataclasses.replace(problem, object=shape)


@dataclass(frozen=True)
class Coverage:
    """One shape and noise level's views.

    Attributes:
        views: Views tried.
        d2: Each fitted view's Mahalanobis distance squared of the position error.
        errors: Each fitted view's position error [m], ``(n, 3)``.
        us: Each fitted view's ``u``.
        refused: Views refused, by the refusal's kind.
    """

    views: int
    d2: np.ndarray
    errors: np.ndarray
    us: np.ndarray
    refused: dict[str, int]

    def inside(self, level: float = 0.95) -> float:
        """The share of fitted views inside the reported ``level`` region (chi-square,
        3 dof).

        Args:
            level: The region's probability, in ``(0, 1)``.

        Returns:
            The share in ``[0, 1]``; NaN when no view was fitted.
        """
        from scipy.stats import chi2

        return float(np.mean(self.d2 <= chi2.ppf(level, 3))) if self.d2.size else math.nan

    def row(self) -> dict[str, Any]:
        """The table's columns (coverage at 95 % with its Wilson interval).

        Returns:
            ``views, fitted, inside_95, ci_low, ci_high, mean_error_mm, max_error_mm,
            mean_u, refused`` (errors [mm]; NaN where no view was fitted).
        """
        fitted = int(self.d2.size)
        hits = int(np.count_nonzero(self.d2 <= CHI2_3_95))
        low, high = wilson_interval(hits, fitted)
        norms = np.linalg.norm(self.errors, axis=1) * 1e3 if fitted else np.zeros(0)
        return {
            "views": self.views,
            "fitted": fitted,
            "inside_95": hits / fitted if fitted else math.nan,
            "ci_low": low,
            "ci_high": high,
            "mean_error_mm": float(np.mean(norms)) if fitted else math.nan,
            "max_error_mm": float(np.max(norms)) if fitted else math.nan,
            "mean_u": float(np.mean(self.us)) if fitted else math.nan,
            "refused": sum(self.refused.values()),
        }


def wilson_interval(successes: int, trials: int, z: float = 1.959964) -> tuple[float, float]:
    """The Wilson score interval of a rate.

    Args:
        successes: Successes counted.
        trials: Trials counted.
        z: The standard normal quantile of the level (95 % by default).

    Returns:
        ``(low, high)`` in ``[0, 1]``; NaN for no trials.
    """
    if trials == 0:
        return math.nan, math.nan
    p = successes / trials
    denominator = 1 + z**2 / trials
    centre = (p + z**2 / (2 * trials)) / denominator
    half = z * math.sqrt(p * (1 - p) / trials + z**2 / (4 * trials**2)) / denominator
    return max(0.0, centre - half), min(1.0, centre + half)


def coverage(
    problem: Problem,
    noise: float,
    views: int,
    seed: int = 1,
    options: PerceptionOptions | None = None,
) -> Coverage:
    """Perceive ``views`` views of ``problem``'s object through its scene's camera (view
    ``i`` seeded ``seed + i``) and keep how each view's true position sits in its reported
    position covariance.

    Args:
        problem: The scene; its object is where it truly is.
        noise: The sensor noise scale (multiplies the Kinect v1's standard deviations).
        views: Views to perceive.
        seed: Seed of view 0.
        options: The calibration errors and restarts (default: ``PerceptionOptions()``
            with one fit per view: the coverage is the covariance's, not the median's).

    Returns:
        Each fitted view's error [m] and Mahalanobis distance, and the refusals.
    """
    options = options or dataclasses.replace(PerceptionOptions(), restarts=1)
    assert problem.object is not None
    camera = DepthCamera(problem, camera_of_scene(problem))
    truth = problem.object.pose[:3]
    d2, errors, us = [], [], []
    refused: dict[str, int] = {}
    for i in range(views):
        try:
            seen = perceive(
                problem,
                noise=NoiseOptions(scale=noise),
                depth_camera=camera,
                rng=np.random.default_rng(seed + i),
                options=options,
            )
        except PerceptionError as refusal:
            kind = type(refusal).__name__
            refused[kind] = refused.get(kind, 0) + 1
            continue
        error = seen.pose[:3] - truth
        d2.append(float(error @ np.linalg.pinv(seen.position_covariance) @ error))
        errors.append(error)
        us.append(seen.u)
    return Coverage(
        views,
        np.array(d2),
        np.array(errors).reshape(-1, 3),
        np.array(us),
        refused,
    )


def coverage_table(
    shapes: Sequence[str],
    noises: Sequence[float],
    views: int,
    seed: int = 1,
    options: PerceptionOptions | None = None,
) -> list[tuple[str, float, Coverage]]:
    """:func:`coverage` of every shape at every noise level; the ``k``-th level's views
    are seeded from ``seed + k * SEED_STRIDE`` (the same seeds at every level would draw
    the same camera errors: one sample, not one per level).

    Args:
        shapes: Keys of :data:`CALIBRATION_SHAPES`.
        noises: Sensor noise scales.
        views, seed, options: As for :func:`coverage`.

    Returns:
        ``(shape, noise, coverage)`` for each shape, then each noise level.
    """
    return [
        (
            name,
            noise,
            coverage(calibration_scene(name), noise, views, seed + k * SEED_STRIDE, options),
        )
        for name in shapes
        for k, noise in enumerate(noises)
    ]
