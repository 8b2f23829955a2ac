"""Several views of one object fused into one estimate: each view's pose weighted by its
information (the inverse of its covariance), the covariance the inverse of their sum.

Each view's errors are taken as independent: its sensor noise is, and so are its camera
calibration errors as :mod:`~openup_ompl.perception.extrinsic` draws them (one draw per
view; a real camera moved between the views shares part of its error, which this
fusion would count twice). The poses are combined in the tangent space of the first
view's: position [m] and a small world-frame rotation [rad], as the covariances are. A
direction in which a view's covariance is zero (a turn about a symmetry axis of the
shape, :func:`~openup_ompl.perception.perceive.without_turns`) is no parameter: it
carries no information, and the fused turn there is the first view's (the scene's). The
views' symmetry axes differ by their fits' errors: each covariance is held without turns
about the first view's axes (else a sum of near-zero informations about nearly the same
axis reads as a tenth of a radian squared of variance about it).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from openup_ompl.exceptions import ConfigError, InvalidProblem
from openup_ompl.perception.nominal import nominal_of
from openup_ompl.perception.perceive import Perception, at_estimate, without_turns
from openup_ompl.perception.uncertainty import u_from_covariance
from openup_ompl.scene import Problem

__all__ = ["Fused", "fuse"]


@dataclass(frozen=True)
class Fused:
    """The fused estimate.

    Attributes:
        pose: The object's pose ``[x, y, z, qx, qy, qz, qw]`` [m, unit quaternion], world
            frame, in the scene shape's frame.
        pose_covariance: ``(6, 6)`` covariance of its position [m] and a small world-frame
            rotation [rad].
        u: The hand law's ``u`` from that covariance.
        views: How many views were fused.
    """

    pose: np.ndarray
    pose_covariance: np.ndarray
    u: float
    views: int


def fuse(problem: Problem, perceptions: Sequence[Perception]) -> Fused:
    """Fuse views of ``problem``'s object (:func:`~openup_ompl.perception.perceive.perceive`
    of each) into one pose, its covariance and ``u``.

    Args:
        problem: The scene (its robot, grasp and object: ``u`` is computed at the fused
            estimate, :func:`~openup_ompl.perception.perceive.at_estimate`).
        perceptions: The views' estimates, at least one.

    Returns:
        The fused estimate; with one view, that view's pose and covariance.

    Raises:
        ConfigError: No view given, or a view's covariance not a finite ``(6, 6)``
            matrix.
        InvalidProblem: The scene has no object.
    """
    if not perceptions:
        raise ConfigError("perceptions", "no view", "at least one view's Perception")
    if problem.object is None:
        raise InvalidProblem("the scene has no [object]")
    first = pin.XYZQUATToSE3(perceptions[0].pose).rotation
    axes = nominal_of(problem.object).symmetry_axes(first)
    information = np.zeros((6, 6))
    weighted = np.zeros(6)
    for k, seen in enumerate(perceptions):
        covariance = np.asarray(seen.pose_covariance, dtype=float)
        if covariance.shape != (6, 6) or not np.all(np.isfinite(covariance)):
            raise ConfigError(
                f"perceptions[{k}].pose_covariance", covariance.shape, "a finite 6 x 6 matrix"
            )
        covariance = without_turns(covariance, axes)
        turn = pin.log3(pin.XYZQUATToSE3(seen.pose).rotation @ first.T)
        tangent = np.concatenate([seen.pose[:3], turn])
        view_information = np.linalg.pinv(covariance, rcond=1e-12, hermitian=True)
        information += view_information
        weighted += view_information @ tangent
    covariance = np.linalg.pinv(information, rcond=1e-12, hermitian=True)
    tangent = covariance @ weighted
    rotation = np.asarray(pin.exp3(tangent[3:])) @ first
    pose = np.asarray(pin.SE3ToXYZQUAT(pin.SE3(rotation, tangent[:3])), dtype=float)
    covariance = without_turns(0.5 * (covariance + covariance.T), axes)
    u = u_from_covariance(
        covariance[:3, :3],
        covariance[3:, 3:],
        at_estimate(problem, pose),
        cross_covariance=covariance[:3, 3:],
    )
    return Fused(pose, covariance, u, len(perceptions))
