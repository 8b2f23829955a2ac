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

from openup_ompl.perception.superquadric import (
    EXPONENTS,
    N_PARAMETERS,
    POSITION,
    ROTATION,
    Superquadric,
    _hidden_faces,
)

__all__ = ["COVARIANCES", "Outline", "SuperquadricFit", "measurement_rows", "parameter_covariance"]

COVARIANCES = ("classic", "sandwich")


#: A superquadric exponent below this makes the faces it joins meet at an edge (rounded
#: over a few per cent of the half-size: less than a pixel); above it the surface curves.
SHARP = 0.5


@dataclass(frozen=True)
class Outline:
    """Where the view sees the object's edges: what measures a face its points do not.

    A face the camera does not see (a box's back, a can's base) bounds the object only
    where its edge meets the outline, known to a pixel: ``Delta = depth / f`` spread
    uniformly (variance ``Delta^2 / 12``) plus the sensor's lateral noise. The fitted
    superquadric's edges are sharper than a pixel, so the few points that happen to fall
    in its rounding carry no such information (their number is chance: ``u`` jumped
    between seeds); the covariance counts the outline instead
    (:meth:`SuperquadricFit.pose_covariance`).

    Attributes:
        points: The fitted points [m], world frame, shape ``(n, 3)``.
        camera: The camera's position [m], world frame.
        focal: Its focal length [px].
        lateral: The sensor's lateral noise [m] at the object (its noise scale included).
        max_incidence: The sensor's grazing limit [deg]: a face seen beyond it gives no
            point, and is measured by its edge whatever points the noise put on it.
    """

    points: np.ndarray
    camera: np.ndarray
    focal: float
    lateral: float
    max_incidence: float = 90.0  # [deg]


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
            points', the support's, then the size prior's), for :meth:`conditioned`.
        residuals: Their residuals [m].
        kind: The covariance estimator (:data:`COVARIANCES`).
        prior_rows: How many of the last rows are the size prior's
            (:class:`~openup_ompl.perception.fit.SizePrior`; 0: none).
        solid: The solid the fit held (``"box"``, ``"cylinder"``, ``"sphere"``; ``None``:
            a superquadric).
        hidden: The solid's faces (``+x, -x, +y, -y, +z, -z``) its exact distance left out,
            shape ``(6,)`` (``None``: none), for :meth:`pose_covariance`'s outline.
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
    prior_rows: int = 0
    solid: str | None = None
    hidden: np.ndarray | None = None

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
        outline: Outline | None = None,
    ) -> np.ndarray:
        """``(6, 6)`` covariance of the centre [m] and a small world-frame rotation [rad],
        world frame, with the parameters ``fixed`` held (:meth:`conditioned`).

        With ``size_sigma`` [m] the pose and the half-sizes are estimated together, the
        scene's dimensions a measurement of the half-sizes with standard deviation
        ``size_sigma``: ``Sigma`` is the pose block of ``(A^T A / s^2 + P)^-1``, ``A =
        [J_p, J_a]`` the points' and the support's Jacobian in the pose and size columns
        (the half-sizes of one of ``groups`` err together: a round section's two radii are
        one radius), ``P = diag(0, size_sigma^-2)``; the exponents are *considered*: their
        fitted covariance moves the pose through that solve. Where the points measure a
        size (both faces of a box seen, a can's curved front) its error follows the
        sensor noise; where they do not (a box's depth seen from its front alone: centre
        plus half-size is what the points fix) the ``outline``'s edge and the prior bound
        it. Left free instead, those trade-offs had a noise-dependent variance (``u``
        jumped between seeds); with the half-sizes held at the fit and ``size_sigma`` each
        added in full (the consider covariance), the prior swamped the noise (the box's
        and the wall can's lateral sigma read 2 mm at every noise: ``u`` did not grow).

        Args:
            fixed: Indices in :data:`PARAMETERS` of the parameters held.
            size_sigma: Standard deviation [m] of each half-size (``0``: the shape free).
            groups: Indices of the half-sizes that err together, one tuple per group.
            outline: The view's edges (:class:`Outline`): with ``size_sigma``, a face
                its points do not see is measured by its edge in the outline, and the
                points in the fit's sub-pixel rounding of an edge count for no size.

        Returns:
            The covariance, shape ``(6, 6)``: position [m^2], rotation [rad^2] and their
            cross terms, world frame.
        """
        if size_sigma <= 0 or self.jacobian is None or self.residuals is None:
            covariance = self.conditioned(fixed)
        else:
            covariance = self._joint(fixed, size_sigma, groups, outline)
        frame = np.zeros((6, 6))
        frame[:3, :3] = np.eye(3)
        frame[3:, 3:] = self.superquadric.rotation
        block = covariance[np.ix_(np.r_[POSITION, ROTATION], np.r_[POSITION, ROTATION])]
        return np.asarray(frame @ block @ frame.T)

    def _joint(
        self,
        fixed: Sequence[int],
        size_sigma: float,
        groups: Sequence[Sequence[int]],
        outline: Outline | None,
    ) -> np.ndarray:
        """:meth:`pose_covariance`'s ``(11, 11)`` form with the sizes estimated jointly."""
        assert self.jacobian is not None and self.residuals is not None
        n = self.points
        variance = float(self.residuals[:n] @ self.residuals[:n] / (n - N_PARAMETERS))
        data = self.jacobian[: self.jacobian.shape[0] - self.prior_rows]
        edges = np.zeros((0, N_PARAMETERS))
        if outline is not None:
            data, edges = self._edges(data, outline)
        pose = [k for k in range(POSITION.start, ROTATION.stop) if k not in set(fixed)]

        def columns(rows: np.ndarray) -> np.ndarray:
            sizes = [rows[:, list(group)].sum(axis=1) for group in groups]
            return np.column_stack([rows[:, pose], *sizes])

        a = columns(data)
        scale = np.linalg.norm(a, axis=0)
        scale[scale == 0] = 1.0
        information = (a / scale).T @ (a / scale) / variance
        information += (columns(edges) / scale).T @ (columns(edges) / scale)
        prior = np.zeros(a.shape[1])
        prior[len(pose) :] = 1.0 / (size_sigma * scale[len(pose) :]) ** 2
        inverse = np.linalg.pinv(information + np.diag(prior), rcond=1e-12, hermitian=True)
        inverse = inverse / np.outer(scale, scale)
        # The exponents considered, with their fitted (marginal) covariance.
        bend = (inverse @ a.T @ data[:, EXPONENTS] / variance)[: len(pose)]
        exponents = self.covariance[EXPONENTS, EXPONENTS]
        reduced = inverse[: len(pose), : len(pose)] + bend @ exponents @ bend.T
        covariance = np.zeros((N_PARAMETERS, N_PARAMETERS))
        covariance[np.ix_(pose, pose)] = reduced
        return covariance

    def _edges(self, data: np.ndarray, outline: Outline) -> tuple[np.ndarray, np.ndarray]:
        """The points' rows without the sizes' information of the points in an edge's
        rounding, and one whitened row per unseen face (hidden from the camera, or with
        no point): its edge ``c . u_i + a_i`` (sign by side) measured across the line of
        sight (:class:`Outline`).

        A held solid's rows are the Jacobian of its exact distance, which already gives
        each point the sizes of the face (or the edge) it lies nearest to, and no
        information on the faces that distance left out (``hidden``); its faces are the
        fit's, so its rows are kept whole. Judged again here (by the incidence alone, and
        each point on the face of its largest ratio to the half-sizes), the two disagreed:
        a point near an edge was counted on one face while its residual measured another,
        its size column cleared, and its row then measured the centre alone (the clutter
        box's ``u`` read 0.22 on one seed and 0.39 on three, from three such points)."""
        sq = self.superquadric
        local = sq.local(outline.points)
        e1, e2 = sq.exponents
        held = self.hidden if self.solid is not None else None  # the fit's own faces
        if held is not None:
            hidden = held.reshape(3, 2).copy()
            scores = np.stack([local - sq.sizes, -local - sq.sizes], axis=-1)  # excess [m]
            if e2 >= SHARP:  # a cylinder's side: the radial excess
                radial = np.hypot(*local[:, :2].T) - sq.sizes[:2].mean()
                scores[:, :2] = radial[:, None, None]
        else:
            box = (sq.rotation[None], sq.position[None], sq.sizes[None])
            hidden = _hidden_faces(*box, outline.camera, outline.max_incidence)[0].reshape(3, 2)
            scores = np.stack([local / sq.sizes, -local / sq.sizes], axis=-1)  # (n, 3, +/-)
            if e2 >= SHARP:  # a round section is one surface, seen
                scores[:, :2] = np.hypot(*(local[:, :2] / sq.sizes[:2]).T)[:, None, None]
        if e2 >= SHARP:
            hidden[:2] = False
        best = np.argmax(np.where(hidden, -np.inf, scores).reshape(-1, 6), axis=1)
        face, side = best // 2, 1 - 2 * (best % 2)
        ray = sq.position - outline.camera
        depth = float(np.linalg.norm(ray))
        sigma = np.sqrt((depth / outline.focal) ** 2 / 12 + outline.lateral**2)
        data, rows = data.copy(), []
        for i, sharp in enumerate((e2 < SHARP, e2 < SHARP, e1 < SHARP)):
            if not sharp:
                continue
            if held is None:
                data[: self.points][face != i, i] = 0.0
            axis = sq.rotation[:, i]
            across = float(np.linalg.norm(np.cross(axis, ray))) / depth
            for k, sign in enumerate((1.0, -1.0)):
                if not hidden[i, k] and np.any((face == i) & (side == sign)):
                    continue  # seen: its points measure it
                row = np.zeros(N_PARAMETERS)
                row[i], row[POSITION] = sign, axis
                rows.append(row * across / sigma)
        return data, np.array(rows).reshape(-1, N_PARAMETERS)

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
    jacobian: np.ndarray,
    residuals: np.ndarray,
    points: int,
    kind: str,
    held: Sequence[int] = (),
) -> tuple[np.ndarray, np.ndarray]:
    """The parameters' covariance at the optimum, and the unobservable directions.

    Args:
        jacobian: ``(r, 11)`` Jacobian of all the fit's residuals.
        residuals: ``(r,)`` the measurements' residuals [m]: the points', then the
            support's (:func:`measurement_rows`).
        points: How many residuals are the points' (they give ``s^2``).
        kind: One of :data:`COVARIANCES`.
        held: Indices in :data:`PARAMETERS` not estimated (a scene's solid's exponents:
            a cylinder is a cylinder): zero rows and columns, and ``jacobian``'s columns
            for them ignored.

    Returns:
        ``(covariance, unobservable)``: the ``(11, 11)`` covariance of
        :data:`PARAMETERS` and the unobservable unit directions, one per row.
    """
    n = points
    variance = float(residuals[:n] @ residuals[:n] / (n - N_PARAMETERS))
    free = [k for k in range(N_PARAMETERS) if k not in set(held)]
    reduced, unseen = _covariance(jacobian[:, free], residuals, variance, kind)
    covariance = np.zeros((N_PARAMETERS, N_PARAMETERS))
    covariance[np.ix_(free, free)] = reduced
    unobservable = np.zeros((len(unseen), N_PARAMETERS))
    unobservable[:, free] = unseen
    return covariance, unobservable


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
