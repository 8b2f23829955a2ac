"""The camera's calibration errors: where the robot believes the camera is (its extrinsic
pose) and a depth bias, drawn per view, applied to the cloud and added to the covariance.

A real camera's pose in the robot's frame is known to millimetres and tenths of a degree
(hand-eye calibration), and a depth sensor's depth carries a bias of millimetres that its
noise model does not: errors common to every point of a view, which no number of points
averages away. Each view draws them once: the camera's believed position is its true one
plus ``N(0, sigma_p^2 I)``, its believed orientation the true one turned by a rotation
vector ``N(0, sigma_a^2 I)`` (world frame), and every depth is offset by ``b ~ N(0,
sigma_b^2)``. The points are measured in the true camera's frame and placed in the world
by the believed pose, as a robot does.

To first order an object at ``p``, seen from the camera at ``c``, is then reported at
``p + dc - [p - c]_x dtheta + b d`` (``d`` the ray to ``p`` over its cosine to the optical
axis) and turned by ``dtheta``: the pose's covariance gains ``sigma_p^2 I + sigma_a^2
[r]_x [r]_x^T + sigma_b^2 d d^T`` in position, ``sigma_a^2 I`` in rotation and ``-sigma_a^2
[r]_x`` between them (:func:`extrinsic_covariance`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from openup_ompl._toml import is_integer, is_number
from openup_ompl.exceptions import ConfigError

__all__ = ["CameraError", "PerceptionOptions", "draw_camera_error", "extrinsic_covariance"]


@dataclass(frozen=True)
class PerceptionOptions:
    """The perception step's error model and estimator settings beyond the sensor noise.

    Attributes:
        camera_position_sigma: Standard deviation [m] of the camera's believed position
            along each world axis (0: its position is known exactly).
        camera_angle_sigma: Standard deviation [deg] of the camera's believed orientation
            about each world axis.
        depth_bias_sigma: Standard deviation [m] of a depth offset common to every pixel of
            a view.
        size_sigma: How well [m] the object's half-sizes are known (the scene names
            them): the fit pulls each half-size to the nearest nominal one with this
            standard deviation (:class:`~openup_ompl.perception.fit.SizePrior`), and the
            pose's covariance estimates the half-sizes with the pose, this their prior
            (:meth:`~openup_ompl.perception.covariance.SuperquadricFit.pose_covariance`);
            0: the sizes free, in the fit and the covariance, as before.
        restarts: Fits of the view (the first on every point, the others on bootstrap
            resamples of the points) whose spread of ``u`` is reported; 1: one fit.
    """

    camera_position_sigma: float = 0.005  # [m]
    camera_angle_sigma: float = 0.5  # [deg]
    depth_bias_sigma: float = 0.002  # [m]
    size_sigma: float = 0.002  # [m]
    restarts: int = 5

    def __post_init__(self) -> None:
        limits = {
            "camera_position_sigma": (self.camera_position_sigma, 1.0, "m"),
            "camera_angle_sigma": (self.camera_angle_sigma, 45.0, "deg"),
            "depth_bias_sigma": (self.depth_bias_sigma, 1.0, "m"),
            "size_sigma": (self.size_sigma, 1.0, "m"),
        }
        for name, (value, high, unit) in limits.items():
            if not (is_number(value) and math.isfinite(value) and 0 <= value <= high):
                raise ConfigError(f"perception.{name}", value, f"a number in [0, {high:g}] {unit}")
        if not (is_integer(self.restarts) and 1 <= self.restarts <= 100):
            raise ConfigError("perception.restarts", self.restarts, "an integer in [1, 100]")

    @classmethod
    def exact(cls) -> PerceptionOptions:
        """A perfectly calibrated camera and one fit: only the sensor noise (the error
        model before these options existed).

        Returns:
            Options with zero calibration errors and one restart.
        """
        return cls(
            camera_position_sigma=0.0, camera_angle_sigma=0.0, depth_bias_sigma=0.0, restarts=1
        )

    @classmethod
    def legacy(cls) -> PerceptionOptions:
        """The sensor noise alone and the shape's parameters free in the covariance: the
        estimator before these options existed.

        Returns:
            :meth:`exact`'s options with ``size_sigma = 0``.
        """
        return dataclasses.replace(cls.exact(), size_sigma=0.0)


@dataclass(frozen=True)
class CameraError:
    """One view's calibration errors.

    Attributes:
        position: Believed minus true camera position [m], world frame.
        rotation: Rotation vector [rad] (world frame) from the true orientation to the
            believed one.
        depth_bias: Depth offset [m] of every pixel.
    """

    position: np.ndarray
    rotation: np.ndarray
    depth_bias: float

    def believed(self, position: np.ndarray, rotation: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The believed camera position and orientation from the true ones.

        Args:
            position: True camera position [m], world frame, shape ``(3,)``.
            rotation: True camera orientation (world from camera), shape ``(3, 3)``.

        Returns:
            ``(position [m], rotation)``, believed, in the same frames.
        """
        return position + self.position, np.asarray(pin.exp3(self.rotation)) @ rotation

    def apply(self, points: np.ndarray, position: np.ndarray, rotation: np.ndarray) -> np.ndarray:
        """World points [m] measured by the true camera (``position``, ``rotation``) as
        the robot places them: depth offset by the bias, then moved by the believed pose.

        Args:
            points: True points [m], world frame, shape ``(n, 3)``.
            position: True camera position [m], world frame, shape ``(3,)``.
            rotation: True camera orientation (world from camera), shape ``(3, 3)``.

        Returns:
            The believed points [m], world frame, shape ``(n, 3)`` (a copy).
        """
        exact = not (np.any(self.position) or np.any(self.rotation) or self.depth_bias)
        if points.size == 0 or exact:  # bit for bit the sensor's points
            return np.array(points, dtype=float)
        camera = (np.asarray(points, dtype=float) - position) @ rotation
        depth = np.maximum(camera[:, 2:3], 1e-6)
        camera = camera * (1.0 + self.depth_bias / depth)
        believed_position, believed_rotation = self.believed(position, rotation)
        return np.asarray(camera @ believed_rotation.T + believed_position)

    def move_height(self, point: np.ndarray, position: np.ndarray, rotation: np.ndarray) -> float:
        """The believed world height of one true world point (the support's).

        Args:
            point: True point [m], world frame, shape ``(3,)``.
            position, rotation: The true camera pose, as for :meth:`apply`.

        Returns:
            Its believed height (world z) [m].
        """
        return float(self.apply(np.asarray(point, dtype=float)[None, :], position, rotation)[0, 2])


def draw_camera_error(options: PerceptionOptions, rng: np.random.Generator) -> CameraError:
    """One view's errors, drawn from ``rng`` (seven standard normals, whatever the sigmas:
    the stream after them does not depend on the options).

    Args:
        options: The calibration errors' standard deviations.
        rng: The view's generator (seven draws taken).

    Returns:
        The view's errors.
    """
    draws = rng.standard_normal(7)
    return CameraError(
        position=draws[:3] * options.camera_position_sigma,
        rotation=draws[3:6] * math.radians(options.camera_angle_sigma),
        depth_bias=float(draws[6] * options.depth_bias_sigma),
    )


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def extrinsic_covariance(
    options: PerceptionOptions, camera: np.ndarray, rotation: np.ndarray, target: np.ndarray
) -> np.ndarray:
    """The ``(6, 6)`` covariance (position [m], rotation [rad]; world frame) that the
    calibration errors add to the pose of an object at ``target`` seen from a camera at
    ``camera`` with orientation ``rotation`` (columns x right, y down, z forward).

    Args:
        options: The calibration errors' standard deviations.
        camera: Camera position [m], world frame, shape ``(3,)``.
        rotation: Camera orientation (world from camera), shape ``(3, 3)``.
        target: The object's position [m], world frame, shape ``(3,)``.

    Returns:
        The covariance, shape ``(6, 6)``: position [m^2], rotation [rad^2] and their
        cross terms [m rad], world frame.
    """
    r = np.asarray(target, dtype=float) - np.asarray(camera, dtype=float)
    angle = math.radians(options.camera_angle_sigma) ** 2
    skew = _skew(r)
    ray = r / max(float(r @ rotation[:, 2]), 1e-6)  # a unit depth change moves p by this
    covariance = np.zeros((6, 6))
    covariance[:3, :3] = (
        options.camera_position_sigma**2 * np.eye(3)
        + angle * skew @ skew.T
        + options.depth_bias_sigma**2 * np.outer(ray, ray)
    )
    covariance[3:, 3:] = angle * np.eye(3)
    covariance[:3, 3:] = -angle * skew
    covariance[3:, :3] = covariance[:3, 3:].T
    return covariance
