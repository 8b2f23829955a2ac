"""A scene's solid is fitted with its exponents held (issue 34): they are the solid's, not
estimated, so its covariance may not count them (the wall's can once reported a position
sigma of 633 mm from them)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

import openup_ompl as oo
from openup_ompl.perception import NoiseOptions, perceive
from openup_ompl.perception.camera import DepthCamera, camera_of_scene
from openup_ompl.perception.covariance import parameter_covariance
from openup_ompl.perception.extrinsic import PerceptionOptions
from openup_ompl.perception.superquadric import EXPONENTS, N_PARAMETERS, POSITION

UNSEEN = Path(__file__).resolve().parent.parent / "benchmarks" / "unseen" / "panda"


def test_held_parameters_carry_no_covariance() -> None:
    """Held parameters get zero rows and columns; the others get s^2 (J^T J)^-1 of the rest."""
    rng = np.random.default_rng(5)
    jacobian = rng.normal(size=(60, N_PARAMETERS))
    jacobian[:, 3:5] = 0.0
    jacobian[:-1, 7] *= 0.05  # the height: measured by the resting row, as strongly as
    jacobian[-1, 7] = 8.0  # the points together (an object standing on its support)
    jacobian[-1, 3:5] = [1e-2, 5e-5]  # its surface samples move with the exponents
    residuals = rng.normal(0.0, 1e-3, 60)
    held, _ = parameter_covariance(jacobian, residuals, 59, "classic", [3, 4])
    free = [k for k in range(N_PARAMETERS) if k not in (3, 4)]
    variance = residuals[:59] @ residuals[:59] / (59 - N_PARAMETERS)
    alone = variance * np.linalg.inv(jacobian[:, free].T @ jacobian[:, free])
    assert np.all(held[EXPONENTS] == 0.0) and np.all(held[:, EXPONENTS] == 0.0)
    assert np.allclose(held[np.ix_(free, free)], alone, rtol=1e-9, atol=0.0)
    considered, _ = parameter_covariance(jacobian, residuals, 59, "classic")
    assert considered[7, 7] > 10 * held[7, 7]  # estimated, they took the height's row


def test_the_wall_cans_covariance_is_its_solids() -> None:
    """The wall can's view that read a 633 mm sigma: no exponent covariance, sigmas < 2 mm."""
    problem = oo.load_scene(UNSEEN / "wall_window.toml")
    options = dataclasses.replace(camera_of_scene(problem), azimuth=-81.119341)
    camera = DepthCamera(problem, options)
    for seed in (1, 2, 3, 4):
        seen = perceive(
            problem,
            noise=NoiseOptions(scale=1.0),
            depth_camera=camera,
            rng=np.random.default_rng(seed),
            options=PerceptionOptions.exact(),
        )
        assert np.all(seen.fit.covariance[EXPONENTS] == 0.0)
        assert np.all(seen.fit.covariance[:, EXPONENTS] == 0.0)
        sigma = np.sqrt(np.diag(seen.pose_covariance[:3, :3]))
        assert np.all(sigma < 0.002), (seed, sigma)
        assert seen.u < 0.4, (seed, seen.u)
        assert np.linalg.norm(seen.fit.covariance[POSITION, POSITION]) > 0
