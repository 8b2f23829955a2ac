"""``u`` follows the sensor noise and holds still over seeds (issue 34): the sizes are
estimated with the pose, the scene's dimensions a prior; an edge is measured by the
outline, not by the points that fall in the fit's rounding of it; every start of the fit is
solved."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import openup_ompl as ou
from openup_ompl.perception import NoiseOptions, Perception, perceive
from openup_ompl.perception.camera import CameraOptions, DepthCamera, camera_of_scene
from openup_ompl.perception.extrinsic import PerceptionOptions

UNSEEN = Path(__file__).resolve().parent.parent / "benchmarks" / "unseen" / "panda"


def _views(problem: ou.Problem, cam: DepthCamera) -> list[tuple[int, Perception]]:
    """The perception of seeds 1-4 at noise 1, the sensor noise alone."""
    return [
        (
            seed,
            perceive(
                problem,
                noise=NoiseOptions(scale=1.0),
                depth_camera=cam,
                rng=np.random.default_rng(seed),
                options=PerceptionOptions.exact(),
            ),
        )
        for seed in (1, 2, 3, 4)
    ]


def _us(scene: str, noise: float, camera: CameraOptions | None = None) -> list[float]:
    """``u`` of seeds 1-4 through the scene's camera (or ``camera``), sensor noise alone."""
    problem = ou.load_scene(UNSEEN / f"{scene}.toml")
    cam = DepthCamera(problem, camera or camera_of_scene(problem))
    return [
        perceive(
            problem,
            noise=NoiseOptions(scale=noise),
            depth_camera=cam,
            rng=np.random.default_rng(seed),
            options=PerceptionOptions.exact(),
        ).u
        for seed in (1, 2, 3, 4)
    ]


@pytest.mark.parametrize("scene", ["clutter_left", "pillars"])
def test_u_grows_with_the_noise_and_holds_over_seeds(scene: str) -> None:
    """A box seen from one side and a can: mean u rises 0.5 -> 1 -> 3, spread <= 0.15 at
    noise 0.5 and 1 (the box's was 0.48 when its rounded edges counted, 0.17-0.20 when its
    covariance judged faces apart from its distance)."""
    cells = {noise: _us(scene, noise) for noise in (0.5, 1.0, 3.0)}
    means = [float(np.mean(us)) for us in cells.values()]
    assert np.all(np.diff(means) > 0), means
    for noise in (0.5, 1.0):
        assert max(cells[noise]) - min(cells[noise]) <= 0.15, (noise, cells[noise])


def test_a_held_box_u_does_not_depend_on_the_frame_it_ends_in() -> None:
    """The clutter box at noise 0.5: its fits end in two of the box's equivalent frames
    (its long side along the superquadric's z or x) and read one u (0.22 on one frame and
    0.39 on the other when its covariance judged faces apart from its distance)."""
    problem = ou.load_scene(UNSEEN / "clutter_left.toml")
    cam = DepthCamera(problem, camera_of_scene(problem))
    seen = [
        perceive(
            problem,
            noise=NoiseOptions(scale=0.5),
            depth_camera=cam,
            rng=np.random.default_rng(seed),
            options=PerceptionOptions.exact(),
        )
        for seed in (1, 2, 3, 4)
    ]
    frames = {int(np.argmax(view.fit.superquadric.sizes)) for view in seen}
    assert len(frames) >= 2, frames
    us = [view.u for view in seen]
    assert max(us) - min(us) <= 0.03, us


def test_the_size_prior_does_not_swamp_the_noise() -> None:
    """The box seen from one side: u at noise 0.5 well below the 0.8 that 2 mm of size
    error added in full gave at every noise."""
    assert max(_us("clutter_left", 0.5)) < 0.5


def test_every_start_is_solved_in_the_drawer() -> None:
    """The drawer's box from elevation 20, azimuth 46, noise 1: within 5 mm on every seed
    (the start the points alone preferred fitted it lying, 24-30 mm off on seeds 2 and 4;
    a side holding points judged hidden, 5.8 mm on seed 2)."""
    problem = ou.load_scene(UNSEEN / "side_drawer.toml")
    cam = DepthCamera(problem, CameraOptions(elevation=20.0, azimuth=46.0))
    assert problem.object is not None
    for seed, seen in _views(problem, cam):
        error = float(np.linalg.norm(seen.pose[:3] - problem.object.pose[:3]))
        assert error < 0.005, (seed, error)


def test_a_cans_section_is_fitted_round() -> None:
    """The scene says the can is a cylinder: its fitted radii agree to 0.1 mm, and the
    centre is within 1.5 mm on seeds 1-4 at noise 1 (an elliptical section moved it 1.9)."""
    problem = ou.load_scene(UNSEEN / "pillars.toml")
    cam = DepthCamera(problem, camera_of_scene(problem))
    assert problem.object is not None
    for seed, seen in _views(problem, cam):
        a1, a2, _ = seen.fit.superquadric.sizes
        assert abs(a1 - a2) < 1e-4, (seed, a1, a2)
        assert np.linalg.norm(seen.pose[:3] - problem.object.pose[:3]) < 0.0015
