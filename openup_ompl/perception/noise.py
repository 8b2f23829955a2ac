"""The depth sensor's noise: Nguyen, Izadi & Lovell (2012), for the Kinect v1.

C. V. Nguyen, S. Izadi and D. Lovell, "Modeling Kinect Sensor Noise for Improved 3D
Reconstruction and Tracking", 3DIMPVT 2012, pp. 524-530, eqs. (5) and (6), fitted for
10 deg < theta < 60-70 deg and depths of 0.5-3 m:

* axial (along the optical axis): ``sigma_z(z, theta) = 0.0012 + 0.0019 (z - 0.4)^2
  + 0.0001 / sqrt(z) * theta^2 / (pi/2 - theta)^2`` [m], ``z`` the depth [m] and
  ``theta`` the angle between the ray and the surface normal;
* lateral (in the image plane): ``sigma_L(theta) = 0.8 + 0.035 theta / (pi/2 - theta)``
  [px] of the Kinect's 585 px focal length, i.e. ``sigma_L z / 585`` [m]; the lateral
  noise is a property of the sensor, so it stays the same in metres whatever the
  simulated image's resolution.

Beyond ``max_incidence`` the structured-light pattern is lost and the Kinect returns no
depth: such points drop out (the model is not fitted there either). Each coordinate's
noise is independent and Gaussian, as in the paper's model; ``scale`` multiplies both
standard deviations (0: a noise-free sensor, the dropout kept).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from openup_ompl._toml import is_number
from openup_ompl.exceptions import ConfigError
from openup_ompl.perception.camera import DepthView

__all__ = [
    "KINECT_FOCAL",
    "NoiseOptions",
    "PointCloud",
    "kinect_sigmas",
    "noise_covariance",
    "noisy_cloud",
    "normal_sigma",
]

#: The Kinect v1's depth focal length [px] (640 x 480), the unit of Nguyen's lateral noise.
KINECT_FOCAL = 585.0


@dataclass(frozen=True)
class NoiseOptions:
    """The sensor noise model's settings.

    Attributes:
        scale: Multiplies the axial and lateral standard deviations (1: the Kinect v1).
        max_incidence: Rays meeting the surface more obliquely than this [deg] drop out.
        lateral_px: Nguyen's lateral noise at normal incidence [px of ``focal``].
        focal: The focal length [px] of ``lateral_px`` (the Kinect's 585 px).
    """

    scale: float = 1.0
    max_incidence: float = 70.0  # [deg]
    lateral_px: float = 0.8  # [px]
    focal: float = KINECT_FOCAL  # [px]

    def __post_init__(self) -> None:
        checks = {
            "scale": (self.scale, 0.0, 100.0),
            "max_incidence": (self.max_incidence, 0.0, 89.9),
            "lateral_px": (self.lateral_px, 0.0, 100.0),
            "focal": (self.focal, 1e-6, 1e6),
        }
        for name, (value, low, high) in checks.items():
            ok = is_number(value)
            if not (ok and math.isfinite(value) and low <= value <= high):
                raise ConfigError(f"noise.{name}", value, f"a finite number in [{low}, {high}]")


def kinect_sigmas(
    depth: np.ndarray, incidence: np.ndarray, options: NoiseOptions | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Axial and lateral standard deviations [m] at ``depth`` [m] and ``incidence`` [rad]
    (Nguyen et al. 2012, eqs. 5-6, times ``options.scale``).

    Args:
        depth: Depths along the optical axis [m], positive.
        incidence: Angles between each ray and the surface normal [rad], in ``[0, pi/2)``.
        options: Noise scale and limits (default :class:`NoiseOptions`).

    Returns:
        ``(sigma_axial, sigma_lateral)`` [m], each the shape of ``depth``.

    Raises:
        ConfigError: A depth not positive or an incidence outside ``[0, pi/2)``, where
            the model has no meaning.
    """
    depth, incidence = np.asarray(depth, dtype=float), np.asarray(incidence, dtype=float)
    if not np.all(np.isfinite(depth) & (depth > 0)):
        raise ConfigError("depth", depth.tolist(), "positive finite depths [m]")
    if not np.all((incidence >= 0) & (incidence < math.pi / 2)):
        raise ConfigError("incidence", incidence.tolist(), "angles in [0, pi/2) rad")
    return _sigmas(depth, incidence, options or NoiseOptions())


def _sigmas(
    depth: np.ndarray, incidence: np.ndarray, options: NoiseOptions
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`kinect_sigmas` without its checks (the sensor's own depths and incidences,
    the latter capped at ``max_incidence``)."""
    grazing = incidence / (math.pi / 2 - incidence)
    axial = 0.0012 + 0.0019 * (depth - 0.4) ** 2 + 0.0001 / np.sqrt(depth) * grazing**2
    lateral_px = options.lateral_px + 0.035 * grazing
    lateral = lateral_px * depth / options.focal
    return options.scale * axial, options.scale * lateral


@dataclass(frozen=True)
class PointCloud:
    """The object's measured points, and what was dropped.

    Attributes:
        points: ``(N, 3)`` measured points [m], world frame.
        pixels: Their pixel indices (row-major) in the view.
        sigma_axial: Each point's axial standard deviation [m] (the model's, for
            reference; the fit does not use it).
        sigma_lateral: Each point's lateral standard deviation [m].
        dropped: Object pixels dropped at grazing incidence.
        scene_points: ``(M, 3)`` measured points of everything else (for figures).
    """

    points: np.ndarray
    pixels: np.ndarray
    sigma_axial: np.ndarray
    sigma_lateral: np.ndarray
    dropped: int
    scene_points: np.ndarray


def noisy_cloud(
    view: DepthView, options: NoiseOptions | None, rng: np.random.Generator
) -> PointCloud:
    """Apply the noise model to a view and keep the object's points.

    Each valid pixel's camera-frame point ``(x, y, z)`` becomes ``(x + sigma_L n_x,
    y + sigma_L n_y, z + sigma_z n_z)``, ``n`` standard normal; pixels beyond
    ``max_incidence`` are dropped. The object's points are the pixels whose ray hit one of
    the object's geoms (:attr:`DepthView.on_object`).

    Args:
        view: The rendered view.
        options: Noise scale and limits (default :class:`NoiseOptions`).
        rng: The run's random generator.

    Returns:
        The object's noisy points with their pixels and standard deviations, and the
        rest of the scene's points (:class:`PointCloud`).
    """
    options = options or NoiseOptions()
    incidence = view.incidence
    valid = view.hit & (incidence <= math.radians(options.max_incidence))
    depth = view.depth[valid]
    axial, lateral = _sigmas(depth, incidence[valid], options)
    camera = view.camera_points()[valid]
    noise = rng.standard_normal(camera.shape)
    camera = camera + noise * np.column_stack([lateral, lateral, axial])
    world = camera @ view.rotation.T + view.position
    on_object = view.on_object[valid]
    pixels = np.flatnonzero(valid)
    dropped = int(np.count_nonzero(view.on_object & ~valid))
    return PointCloud(
        points=world[on_object],
        pixels=pixels[on_object],
        sigma_axial=axial[on_object],
        sigma_lateral=lateral[on_object],
        dropped=dropped,
        scene_points=world[~on_object],
    )


def noise_covariance(
    position: np.ndarray, rotation: np.ndarray, options: NoiseOptions | None = None
) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """The sensor noise's covariance at each measured point, for the fit's expected
    distance (:func:`~openup_ompl.perception.fit.fit_superquadric`).

    Returns ``covariance(points, normals)`` [m^2]: at each point (world frame) and unit
    normal of the fitted surface, ``diag(sigma_L^2, sigma_L^2, sigma_z^2)`` in the camera
    frame at the incidence between the camera's ray and the normal (capped at
    ``max_incidence``), turned into the world frame; ``options.scale`` included.

    Args:
        position: The camera's position [m], world frame.
        rotation: The camera's orientation (3 x 3, camera to world).
        options: Noise scale and limits (default :class:`NoiseOptions`).

    Returns:
        The function ``covariance(points (n, 3) [m], normals (n, 3)) -> (n, 3, 3)`` [m^2].
    """
    options = options or NoiseOptions()
    cap = math.radians(options.max_incidence)

    def covariance(points: np.ndarray, normals: np.ndarray) -> np.ndarray:
        depth, incidence, _ = _seen(points, normals, position, rotation, cap)
        axial, lateral = _sigmas(depth, incidence, options)
        variances = np.column_stack([lateral**2, lateral**2, axial**2])
        return np.einsum("ij,nj,kj->nik", rotation, variances, rotation)

    return covariance


def _seen(
    points: np.ndarray, normals: np.ndarray, position: np.ndarray, rotation: np.ndarray, cap: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each point's depth [m] in the camera, the incidence [rad] of the camera's ray on
    its normal (capped at ``cap``), and the normals in the camera frame."""
    camera = (points - position) @ rotation
    depth = np.maximum(camera[:, 2], 1e-3)
    rays = camera / np.linalg.norm(camera, axis=1, keepdims=True)
    normal = normals @ rotation
    incidence = np.minimum(np.arccos(np.clip(np.abs(np.sum(rays * normal, 1)), 0, 1)), cap)
    return depth, incidence, normal


def normal_sigma(
    position: np.ndarray, rotation: np.ndarray, options: NoiseOptions | None = None
) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """The sensor's noise along a surface normal, for the fit's weights.

    Returns ``sigma(points, normals)`` [m]: at each measured point (world frame) and unit
    normal of the fitted surface, the incidence is the angle between the camera's ray and
    the normal (capped at ``max_incidence``) and the noise covariance ``diag(sigma_L^2,
    sigma_L^2, sigma_z^2)`` (camera frame) is projected on the normal. Only what a real
    system has is used: the measured points, the fit and the sensor's model.

    Args:
        position: The camera's position [m], world frame.
        rotation: The camera's orientation (3 x 3, camera to world).
        options: Noise scale and limits (default :class:`NoiseOptions`).

    Returns:
        The function ``sigma(points (n, 3) [m], normals (n, 3)) -> (n,)`` [m].
    """
    options = options or NoiseOptions()
    cap = math.radians(options.max_incidence)

    def sigma(points: np.ndarray, normals: np.ndarray) -> np.ndarray:
        depth, incidence, normal = _seen(points, normals, position, rotation, cap)
        axial, lateral = _sigmas(depth, incidence, replace(options, scale=1.0))
        variance = (
            lateral**2 * (normal[:, 0] ** 2 + normal[:, 1] ** 2) + axial**2 * normal[:, 2] ** 2
        )
        return np.sqrt(variance)

    return sigma
