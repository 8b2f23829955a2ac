"""The covariance of a superquadric fit's parameters, and the fit's result.

The covariance of the 11 parameters is the Gauss-Newton one, ``s^2 (J^T J)^-1``, ``s^2 =
sum r^2 / (n - 11)``, with ``J`` the residuals' Jacobian at the optimum (rotation
re-linearised about the fitted orientation, so the rotation block is in the fitted frame) —
the ``classic`` estimator — or its heteroscedasticity-consistent sandwich form (see
:class:`~openup_ompl.perception.fit.FitOptions`). Directions of ``J^T J`` with no
information (a cylinder's yaw about its axis, the sizes of an unseen side...) are given by
a pseudo-inverse and listed in ``unobservable``.

``J`` holds the points' rows and the support's (an equality: the object stands on it), not
the free space's (:class:`~openup_ompl.perception.fit.Silhouette`): those are an
inequality, zero inside the one-pixel band and a penalty beyond it, that bounds the
estimate without measuring it. Counted as measurements with the points' variance, the few
samples a fit pushes past the band (those fits that grew away from the camera, or squared
off a round section) made their covariance millimetres where the error was centimetres
(LWA3 can at noise 4: 50 % inside the 2-sigma ellipse with them, 68 % without; box 74 and
88 %; thin stick 61 and 87 %). Without them the covariance is that of the points and the
support alone, which bounds the bounded estimate's: conservative where only the outline
fixes a side (the box's face seen too obliquely to measure: its lateral sigma 2.2 mm,
median, for an error of 1.0 mm sd).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from openup_ompl.perception.superquadric import N_PARAMETERS, POSITION, ROTATION, Superquadric

__all__ = ["COVARIANCES", "SuperquadricFit", "parameter_covariance"]

COVARIANCES = ("classic", "sandwich")


@dataclass(frozen=True)
class SuperquadricFit:
    """A fitted superquadric and the uncertainty of its parameters.

    Attributes:
        superquadric: The fit.
        covariance: ``(11, 11)`` covariance of :data:`PARAMETERS` (rotation in the fitted
            frame) [m, rad].
        residual_rms: ``s``, the residuals' standard deviation [m] (``n - 11`` dof).
        mean_residual: Mean absolute distance [m] of the points to the fit (the
            paper's "fitting error" candidate for ``u``).
        points: Points fitted.
        evaluations: Residual evaluations spent (every start).
        unobservable: Unit directions in parameter space (rows, ``J^T J``-scaled) that
            the cloud does not determine.
    """

    superquadric: Superquadric
    covariance: np.ndarray
    residual_rms: float
    mean_residual: float
    points: int
    evaluations: int
    unobservable: np.ndarray = field(default_factory=lambda: np.zeros((0, N_PARAMETERS)))

    @property
    def position_covariance(self) -> np.ndarray:
        """``(3, 3)`` covariance [m^2] of the centre, world frame."""
        return self.covariance[POSITION, POSITION].copy()

    @property
    def rotation_covariance(self) -> np.ndarray:
        """``(3, 3)`` covariance [rad^2] of a small rotation, world frame."""
        rotation = self.superquadric.rotation
        return rotation @ self.covariance[ROTATION, ROTATION] @ rotation.T

    @property
    def diameter(self) -> float:
        """Twice the largest half-size [m] (the paper's "diameter" candidate for ``u``)."""
        return float(2 * np.max(self.superquadric.sizes))


def parameter_covariance(
    jacobian: np.ndarray, residuals: np.ndarray, points: int, free_space: int, kind: str
) -> tuple[np.ndarray, np.ndarray]:
    """The parameters' covariance at the optimum, and the unobservable directions.

    Args:
        jacobian: ``(r, 11)`` Jacobian of all the fit's residuals.
        residuals: ``(r,)`` residuals [m]: the points', then ``free_space`` rows of the
            free space (left out: they bound, not measure), then the support's.
        points: How many residuals are the points' (they give ``s^2``).
        free_space: How many rows follow the points' and are the free space's.
        kind: One of :data:`COVARIANCES`.
    """
    n = points
    variance = float(residuals[:n] @ residuals[:n] / (n - N_PARAMETERS))
    rows = np.r_[0:n, n + free_space : residuals.shape[0]]
    return _covariance(jacobian[rows], residuals[rows], variance, kind)


def _covariance(
    jacobian: np.ndarray, residuals: np.ndarray, variance: float, kind: str
) -> tuple[np.ndarray, np.ndarray]:
    """The parameters' covariance and the unobservable directions (see module docstring).

    ``J^T J`` is inverted after scaling its columns to unit norm (the parameters mix
    metres, radians and exponents); eigenvalues under ``1e-10`` of the largest are
    treated as no information.
    """
    n, p = jacobian.shape
    scale = np.linalg.norm(jacobian, axis=0)
    scale[scale == 0] = 1.0
    scaled = jacobian / scale
    values, vectors = np.linalg.eigh(scaled.T @ scaled)
    keep = values > 1e-10 * values.max()
    inverse = (vectors[:, keep] / values[keep]) @ vectors[:, keep].T
    if kind == "classic":
        middle = variance * (scaled.T @ scaled)
    else:
        weighted = scaled * residuals[:, None]
        middle = weighted.T @ weighted * (n / (n - p))
    covariance = inverse @ middle @ inverse / np.outer(scale, scale)
    return covariance, vectors[:, ~keep].T.copy()
