"""Two views of one object fused (issue 34): the covariance shrinks, the estimate holds."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

import openup_ompl as ou
from openup_ompl.exceptions import ConfigError
from openup_ompl.perception import NoiseOptions, Perception, perceive
from openup_ompl.perception.camera import DepthCamera, camera_of_scene
from openup_ompl.perception.extrinsic import PerceptionOptions
from openup_ompl.perception.fusion import fuse

SCENE = Path(__file__).resolve().parent.parent / "benchmarks" / "unseen" / "panda" / "pillars.toml"


def _views(seed: int, options: PerceptionOptions) -> tuple[ou.Problem, list[Perception]]:
    """The pillars' can from the scene's camera and 60 degrees anticlockwise of it, noise 1."""
    problem = ou.load_scene(SCENE)
    configured = camera_of_scene(problem)
    first = DepthCamera(problem, configured)
    assert problem.object is not None
    away = first.position[:2] - problem.object.pose[:2]
    azimuth = math.degrees(math.atan2(away[1], away[0])) + 60.0
    second = DepthCamera(problem, dataclasses.replace(configured, azimuth=azimuth))
    views = [
        perceive(
            problem,
            noise=NoiseOptions(scale=1.0),
            depth_camera=camera,
            rng=np.random.default_rng(seed + 100 * k),
            options=options,
        )
        for k, camera in enumerate((first, second))
    ]
    return problem, views


@pytest.mark.parametrize("options", [PerceptionOptions.exact(), PerceptionOptions(restarts=1)])
def test_fusing_two_views_shrinks_the_covariance(options: PerceptionOptions) -> None:
    """The fused position covariance is below each view's (Loewner order), its trace
    under 3/4 of the smaller one's, u no larger, no variance about the can's axis, and the
    estimate within 3 mm (sensor noise alone)."""
    for seed in (1, 2):
        problem, views = _views(seed, options)
        fused = fuse(problem, views)
        for view in views:
            gap = np.linalg.eigvalsh(view.pose_covariance[:3, :3] - fused.pose_covariance[:3, :3])
            assert gap.min() >= -1e-9 * np.abs(gap).max()
        # The can stands along world z: no turn about it (a tenth of a rad^2 if summed).
        assert fused.pose_covariance[5, 5] < 1e-2 * np.trace(fused.pose_covariance[3:, 3:])
        traces = [np.trace(view.pose_covariance[:3, :3]) for view in views]
        assert np.trace(fused.pose_covariance[:3, :3]) < 0.75 * min(traces)
        assert fused.u <= min(view.u for view in views) + 1e-12
        assert problem.object is not None
        if options.camera_position_sigma == 0:
            error = np.linalg.norm(fused.pose[:3] - problem.object.pose[:3])
            assert error < 0.003, (seed, error)


def test_one_view_fuses_to_itself() -> None:
    """One view: its own pose and covariance; none: a ConfigError naming the views."""
    problem, views = _views(1, PerceptionOptions.exact())
    fused = fuse(problem, views[:1])
    assert np.allclose(fused.pose_covariance, views[0].pose_covariance, rtol=1e-6, atol=1e-15)
    assert np.allclose(fused.pose[:3], views[0].pose[:3], atol=1e-9)
    assert fused.u == pytest.approx(views[0].u, abs=1e-9)
    with pytest.raises(ConfigError, match="perceptions"):
        fuse(problem, [])
