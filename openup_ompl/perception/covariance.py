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
off a round section) made their covariance millimetres where the error was centimetres.
Without them the covariance is that of the points and the support alone, which bounds the
bounded estimate's: conservative where only the outline fixes a side (a box's face seen
too obliquely to measure).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from openup_ompl.perception.superquadric import N_PARAMETERS, POSITION, ROTATION, Superquadric

__all__ = ["COVARIANCES", "SuperquadricFit", "measurement_rows", "parameter_covariance"]

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
        jacobian: The measurements' rows of the residuals' Jacobian at the optimum (the
            points' and the support's), for :meth:`conditioned`.
        residuals: Their residuals [m].
        kind: The covariance estimator (:data:`COVARIANCES`).
    """

    superquadric: Superquadric
    covariance: np.ndarray
    residual_rms: float
    mean_residual: float
    points: int
    evaluations: int
    unobservable: np.ndarray = field(default_factory=lambda: np.zeros((0, N_PARAMETERS)))
    jacobian: np.ndarray | None = None
    residuals: np.ndarray | None = None
    kind: str = "classic"

    def conditioned(self, fixed: Sequence[int]) -> np.ndarray:
        """The ``(11, 11)`` covariance with the parameters ``fixed`` (indices in
        :data:`PARAMETERS`) held at their fitted values: zero rows and columns for them.
        A turn about a symmetry axis of the fitted shape moves no surface: left free, its
        barely observed variance leaks into the position's through its correlation with
        the sizes and the centre (see :mod:`~openup_ompl.perception.uncertainty`).

        Args:
            fixed: Indices in :data:`PARAMETERS` of the parameters held.

        Returns:
            The covariance [m, rad, unitless exponents; squared and crossed], rotation in
            the fitted frame, shape ``(11, 11)``.
        """
        if not fixed or self.jacobian is None or self.residuals is None:
            return self.covariance.copy()
        free = [k for k in range(N_PARAMETERS) if k not in set(fixed)]
        n = self.points
        variance = float(self.residuals[:n] @ self.residuals[:n] / (n - N_PARAMETERS))
        reduced, _ = _covariance(self.jacobian[:, free], self.residuals, variance, self.kind)
        covariance = np.zeros((N_PARAMETERS, N_PARAMETERS))
        covariance[np.ix_(free, free)] = reduced
        return covariance

    def pose_covariance(
        self,
        fixed: Sequence[int] = (),
        size_sigma: float = 0.0,
        groups: Sequence[Sequence[int]] = ((0,), (1,), (2,)),
    ) -> np.ndarray:
        """``(6, 6)`` covariance of the centre [m] and a small world-frame rotation [rad],
        world frame, with the parameters ``fixed`` held (:meth:`conditioned`).

        With ``size_sigma`` [m] the shape (half-sizes and exponents) is held at the fit
        and its half-sizes' uncertainty, ``size_sigma`` each, is *considered*: ``Sigma =
        s^2 (J_p^T J_p)^-1 + S diag(size_sigma^2) S^T``, ``S = (J_p^T J_p)^-1 J_p^T J_a``
        the pose's shift per half-size error (``J_p``, ``J_a``: the Jacobian's pose and
        size columns; the half-sizes of one of ``groups`` err together: a round section's
        two radii are one radius); the exponents are considered likewise, with their
        fitted covariance. Left free instead, a size and the centre along the line of sight
        trade off (a box's face seen fixes only centre plus half-size, a can's front only
        its curvature): the points do not bound them, the free space does, and the
        points' covariance gave them a noise-dependent variance (``u`` jumped between
        seeds). The scene names the object's dimensions: ``size_sigma`` is how well.

        Args:
            fixed: Indices in :data:`PARAMETERS` of the parameters held.
            size_sigma: Standard deviation [m] of each half-size (``0``: the shape free).
            groups: Indices of the half-sizes that err together, one tuple per group.

        Returns:
            The covariance, shape ``(6, 6)``: position [m^2], rotation [rad^2] and their
            cross terms, world frame.
        """
        if size_sigma <= 0 or self.jacobian is None or self.residuals is None:
            covariance = self.conditioned(fixed)
        else:
            covariance = self._considered(fixed, size_sigma, groups)
        frame = np.zeros((6, 6))
        frame[:3, :3] = np.eye(3)
        frame[3:, 3:] = self.superquadric.rotation
        block = covariance[np.ix_(np.r_[POSITION, ROTATION], np.r_[POSITION, ROTATION])]
        return np.asarray(frame @ block @ frame.T)

    def _considered(
        self, fixed: Sequence[int], size_sigma: float, groups: Sequence[Sequence[int]]
    ) -> np.ndarray:
        """:meth:`pose_covariance`'s ``(11, 11)`` form with the shape considered."""
        assert self.jacobian is not None and self.residuals is not None
        n = self.points
        variance = float(self.residuals[:n] @ self.residuals[:n] / (n - N_PARAMETERS))
        pose = [k for k in range(POSITION.start, ROTATION.stop) if k not in set(fixed)]
        jp = self.jacobian[:, pose]
        ja = np.column_stack([self.jacobian[:, list(group)].sum(axis=1) for group in groups])
        scale = np.linalg.norm(jp, axis=0)
        scale[scale == 0] = 1.0
        inverse = np.linalg.pinv((jp / scale).T @ (jp / scale), rcond=1e-10)
        inverse = inverse / np.outer(scale, scale)
        shift = inverse @ jp.T @ ja
        reduced = variance * inverse + size_sigma**2 * shift @ shift.T
        # The exponents considered too, with their fitted (marginal) covariance.
        bend = inverse @ jp.T @ self.jacobian[:, 3:5]
        reduced = reduced + bend @ self.covariance[3:5, 3:5] @ bend.T
        covariance = np.zeros((N_PARAMETERS, N_PARAMETERS))
        covariance[np.ix_(pose, pose)] = reduced
        return covariance

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
    jacobian: np.ndarray, residuals: np.ndarray, points: int, kind: str
) -> tuple[np.ndarray, np.ndarray]:
    """The parameters' covariance at the optimum, and the unobservable directions.

    Args:
        jacobian: ``(r, 11)`` Jacobian of all the fit's residuals.
        residuals: ``(r,)`` the measurements' residuals [m]: the points', then the
            support's (:func:`measurement_rows`).
        points: How many residuals are the points' (they give ``s^2``).
        kind: One of :data:`COVARIANCES`.

    Returns:
        ``(covariance, unobservable)``: the ``(11, 11)`` covariance of
        :data:`PARAMETERS` and the unobservable unit directions, one per row.
    """
    n = points
    variance = float(residuals[:n] @ residuals[:n] / (n - N_PARAMETERS))
    return _covariance(jacobian, residuals, variance, kind)


def measurement_rows(residuals: np.ndarray, points: int, free_space: int) -> np.ndarray:
    """The rows of the fit's residuals that measure: the points' and the support's, not
    the ``free_space`` rows that follow the points' (they bound, module docstring).

    Args:
        residuals: All the fit's residuals [m], shape ``(r,)``.
        points: How many residuals are the points' (the first ones).
        free_space: How many free-space rows follow them.

    Returns:
        Row indices, shape ``(r - free_space,)``.
    """
    return np.r_[0:points, points + free_space : residuals.shape[0]]


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
