"""The perceived covariance is calibrated for every shape (slow tier): the true position
lies inside the reported 95 % region in at least 80 % of 80 seeded views (noise 0.5 and
4, the camera's calibration errors at their defaults; seeded as the committed table's
first two noise levels, ``benchmarks/perception_calibration.py``), and of 40 with the
sensor noise alone at noise 0.5 and 1."""

from __future__ import annotations

import numpy as np
import pytest

from openup_ompl.perception.calibration import (
    CALIBRATION_SHAPES,
    SEED_STRIDE,
    calibration_scene,
    coverage,
    wilson_interval,
)
from openup_ompl.perception.extrinsic import PerceptionOptions


@pytest.mark.slow
@pytest.mark.parametrize("shape", list(CALIBRATION_SHAPES))
def test_the_reported_95_region_holds_the_truth(shape: str) -> None:
    """At least 80 % of 80 views (40 at noise 0.5, 40 at noise 4) inside, and the
    covariance not inflated past use (at most 100 %, mean error under 25 mm)."""
    problem = calibration_scene(shape)
    cells = [
        coverage(problem, noise, 40, seed=3000 + k * SEED_STRIDE)
        for k, noise in enumerate((0.5, 4.0))
    ]
    d2 = np.concatenate([cell.d2 for cell in cells])
    assert d2.size >= 76  # at most 5 % refused
    inside = float(np.mean(d2 <= 7.815))
    assert inside >= 0.8, (shape, inside)
    errors = np.concatenate([cell.errors for cell in cells])
    assert float(np.mean(np.linalg.norm(errors, axis=1))) < 0.025


def test_the_wilson_interval_brackets_the_rate() -> None:
    """Wilson's interval holds the observed rate and narrows with the trials."""
    low, high = wilson_interval(38, 40)
    assert low < 0.95 < high
    low2, high2 = wilson_interval(380, 400)
    assert low < low2 < 0.95 < high2 < high
    assert wilson_interval(0, 10)[0] == pytest.approx(0.0, abs=1e-12)
    assert wilson_interval(10, 10)[1] == pytest.approx(1.0)


@pytest.mark.slow
@pytest.mark.parametrize("shape", list(CALIBRATION_SHAPES))
def test_the_fit_s_own_covariance_holds_the_truth(shape: str) -> None:
    """The sensor noise alone: at least 80 % of 40 views (20 at noise 0.5, 20 at noise 1,
    seeded as the committed table's) inside the reported 95 % region (the box held 21 of
    40 when it was fitted as a superquadric; 40 of 40 as a box)."""
    problem = calibration_scene(shape)
    exact = PerceptionOptions.exact()
    cells = [
        coverage(problem, noise, 20, seed=3000 + k * SEED_STRIDE, options=exact)
        for k, noise in enumerate((0.5, 1.0))
    ]
    d2 = np.concatenate([cell.d2 for cell in cells])
    assert d2.size == 40
    assert float(np.mean(d2 <= 7.815)) >= 0.8, (shape, d2)
