"""Superquadric fit of an object's point cloud (model: :mod:`~openup_ompl.perception.superquadric`;
covariance: :mod:`~openup_ompl.perception.covariance`).

Each point's residual is its first-order (Taubin) distance to the surface, ``(G - 1) /
|grad G|`` [m] with ``G = F^(e1/2)`` (``G`` grows linearly along every ray from the centre,
so this is the distance along the surface normal up to second order: exactly ``rho - a``
on a cylinder's side). Solina's volume-weighted ``F^e1 - 1`` and the radial distance
``|p| (1 - F^(-e1/2))`` both grow with the point's distance from the centre: on a partial
view they pull the centre away from the seen side by several times the noise; this does not.

``scipy.optimize.least_squares`` (trust-region reflective, exponents and sizes bounded)
is started from the cloud's principal axes, once with each principal axis as the
superquadric's z axis; each start is solved with the view's free space and the lowest cost
wins: the cylinder is only representable with its axis along z, a partial view's principal
axes are not ordered by the object's, and the points alone do not tell a box lying from
one standing (the most promising start on them missed a drawer's box by 2-3 cm).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from openup_ompl._toml import is_integer, is_number
from openup_ompl.exceptions import ConfigError
from openup_ompl.perception.covariance import (
    COVARIANCES,
    SuperquadricFit,
    measurement_rows,
    parameter_covariance,
)
from openup_ompl.perception.likelihood import ROUND, _round_eigen, solid_mahalanobis
from openup_ompl.perception.silhouette import Silhouette
from openup_ompl.perception.superquadric import (
    EXPONENTS,
    N_PARAMETERS,
    SOLIDS,
    _distance,
    _held_faces,
    _hidden_faces,
    _normals,
    _rotations,
    _solid_distance,
    _split,
    _surface_local,
    checked_points,
)

__all__ = ["FitOptions", "Silhouette", "fit_superquadric"]


@dataclass(frozen=True)
class FitOptions:
    """The superquadric fit's settings.

    Attributes:
        min_exponent: Lower bound of ``e1``, ``e2`` (sharper edges are not representable;
            0.05 rounds the last 2 % of a box's half side).
        max_exponent: Upper bound of ``e1``, ``e2`` (2: the superquadric stays convex).
        min_size: Lower bound of the half-sizes [m].
        max_size: Upper bound of the half-sizes [m].
        starts: Principal axes tried as the superquadric's z axis (1 to 3).
        trial_evaluations: Residual evaluations of each start on the points alone (the
            lowest-cost one sets the weights), before each is solved to convergence.
        max_evaluations: Residual evaluations of each start's solve.
        covariance: ``"classic"``: ``s^2 (J^T J)^-1``; ``"sandwich"``: ``(J^T J)^-1 J^T
            diag(r^2) J (J^T J)^-1 n / (n - 11)`` (White's estimator: the same when every
            residual has one variance, right when they differ, as the depth noise does
            with depth and incidence).
    """

    min_exponent: float = 0.05
    max_exponent: float = 2.0
    min_size: float = 0.002  # [m]
    max_size: float = 1.0  # [m]
    starts: int = 3
    trial_evaluations: int = 5
    max_evaluations: int = 200
    covariance: str = "classic"

    def __post_init__(self) -> None:
        if not (
            is_number(self.min_exponent)
            and is_number(self.max_exponent)
            and 0.01 <= self.min_exponent < self.max_exponent <= 4.0
        ):
            raise ConfigError(
                "fit.min_exponent, max_exponent",
                (self.min_exponent, self.max_exponent),
                "0.01 <= min_exponent < max_exponent <= 4",
            )
        if not (is_number(self.min_size) and is_number(self.max_size)) or not (
            0 < self.min_size < self.max_size
        ):
            raise ConfigError(
                "fit.min_size, max_size", (self.min_size, self.max_size), "0 < min < max [m]"
            )
        if not is_integer(self.starts) or self.starts not in (1, 2, 3):
            raise ConfigError("fit.starts", self.starts, "1, 2 or 3")
        if not (is_integer(self.max_evaluations) and self.max_evaluations >= 10):
            raise ConfigError("fit.max_evaluations", self.max_evaluations, "at least 10")
        if not (is_integer(self.trial_evaluations) and self.trial_evaluations >= 1):
            raise ConfigError("fit.trial_evaluations", self.trial_evaluations, "at least 1")
        if self.covariance not in COVARIANCES:
            raise ConfigError("fit.covariance", self.covariance, f"one of {COVARIANCES}")


def _batch_residuals(
    xs: np.ndarray,
    points: np.ndarray,
    reference: np.ndarray,
    silhouette: Silhouette | None = None,
    weights: np.ndarray | None = None,
    prior: SizePrior | None = None,
    solid: str | None = None,
    hidden: np.ndarray | None = None,
    spread: np.ndarray | None = None,
) -> np.ndarray:
    """Residuals of ``k`` parameter sets at once, ``(k, n [+ m [+ 1]] [+ 3])`` (the
    points, the silhouette's samples, the resting on the support, the sizes' prior): one
    vectorised pass for a whole finite-difference Jacobian (12 sets cost about two single
    evaluations). A ``solid``'s points are measured by their exact distance to its faces
    not ``hidden``, or their Mahalanobis distance under the noise's covariances ``spread``
    (:func:`_points_distance`)."""
    rotations = reference @ _rotations(xs[:, 8:11])
    distance = _points_distance(xs, points, rotations, solid, hidden, spread)
    if weights is not None:
        distance = distance * weights
    parts = [distance]
    if silhouette is not None:
        sizes, e1, e2 = xs[:, None, 0:3], xs[:, 3:4], xs[:, 4:5]
        surface = _surface_local(sizes, e1, e2, silhouette.samples)
        world = surface @ rotations.transpose(0, 2, 1) + xs[:, None, 5:8]
        parts.append(silhouette.excess(world))
        if silhouette.support is not None:
            # Standing on it: the lowest sample on the support, as strongly as the points.
            resting = (world[..., 2].min(axis=1) - silhouette.support) * math.sqrt(points.shape[0])
            parts.append(resting[:, None])
    if prior is not None:
        parts.append(prior.rows(xs[:, 0:3]))
    return np.concatenate(parts, axis=1)


def _points_distance(
    xs: np.ndarray,
    points: np.ndarray,
    rotations: np.ndarray,
    solid: str | None,
    hidden: np.ndarray | None = None,
    spread: np.ndarray | None = None,
) -> np.ndarray:
    """The points' signed distances [m] to ``k`` parameter sets' surfaces (``rotations``:
    their ``(k, 3, 3)`` frames in the world), ``(k, n)``: the superquadric's first-order
    one, or the exact one to the ``solid``'s faces not ``hidden`` (``(6,)``,
    :func:`~openup_ompl.perception.superquadric._hidden_faces`; held, not a function of the
    parameters: a fit free to turn a face past the grazing limit would free its points),
    Euclidean or, with the points' noise covariances ``spread`` (``(n, 3, 3)``, world
    frame, scaled to a common sigma), Mahalanobis
    (:func:`~openup_ompl.perception.likelihood.solid_mahalanobis`)."""
    local = (points[None] - xs[:, None, 5:8]) @ rotations
    sizes, e1, e2 = xs[:, None, 0:3], xs[:, 3:4], xs[:, 4:5]
    if solid is None:
        return np.asarray(_distance(local, sizes, e1, e2))
    if spread is None:
        return _solid_distance(local, sizes, solid, hidden)
    if solid == "sphere":  # the noise's eigenvectors turned into each frame, not found again
        values, vectors = np.linalg.eigh(spread)
        turned = np.einsum("kai,nab->knib", rotations, vectors, optimize=True)
        return _round_eigen(local, sizes.mean(axis=-1), values[None], turned)
    turned = np.einsum("kai,nab,kbj->knij", rotations, spread, rotations, optimize=True)
    return solid_mahalanobis(local, sizes, solid, turned, hidden)


_ORDERS = tuple(itertools.permutations(range(3)))


@dataclass(frozen=True)
class SizePrior:
    """What the scene says of the object's size: the fitted half-sizes are pulled to the
    nominal ones in the order that matches them best (whichever axes the fit gave them),
    as measurements of standard deviation ``sigma`` against points of standard deviation
    ``noise``.

    The half-sizes of each pair in ``ties`` are held equal, as strongly as all the points
    together (``tie``: the square root of their number), as the support is: a scene's
    cylinder has a round section, its ball is round (left free, a can's partial view fits
    an elliptical section about as well, its centre moved by millimetres).

    Attributes:
        half: The nominal half-extents [m].
        sigma: How well they are known [m].
        noise: The points' residuals' standard deviation [m] (the rows' scale).
        ties: Pairs of the superquadric's half-sizes (indices) held equal.
        tie: Weight of the ties' rows.
        ordered: The half-sizes are the nominal ones in their order (a cylinder's axis is
            the superquadric's z once its section is held round: matched freely, a fit
            collapsed onto a can's top took its radius for its height).
    """

    half: np.ndarray
    sigma: float
    noise: float
    ties: tuple[tuple[int, int], ...] = ()
    tie: float = 1.0
    ordered: bool = False

    def rows(self, sizes: np.ndarray) -> np.ndarray:
        """The half-sizes' gaps to the nominal ones, in the order that matches them best.

        Args:
            sizes: Half-sizes [m], shape ``(k, 3)``.

        Returns:
            Residuals [m], shape ``(k, 3 + len(ties))``: the gaps scaled by ``noise /
            sigma``, then the tied half-sizes' differences by ``tie``.
        """
        half = np.asarray(self.half, dtype=float)
        orders = _ORDERS[:1] if self.ordered else _ORDERS
        gaps = np.stack([sizes - half[list(order)] for order in orders])  # (6, k, 3)
        best = np.argmin(np.sum(gaps**2, axis=2), axis=0)
        gap = gaps[best, np.arange(sizes.shape[0])]
        tied = [self.tie * (sizes[:, i] - sizes[:, j]) for i, j in self.ties]
        return np.column_stack([gap * (self.noise / self.sigma), *tied])


def _residuals(x: np.ndarray, *args: Any) -> np.ndarray:
    return _batch_residuals(x[None], *args)[0]


#: Typical magnitudes of the parameters' changes (``least_squares``' ``x_scale``).
_X_SCALE = np.array([0.01] * 3 + [0.1] * 2 + [0.01] * 3 + [0.1] * 3)
#: Finite-difference steps of the parameters (sizes and position [m], exponents, [rad]).
_STEPS = np.array([1e-7] * 3 + [1e-6] * 2 + [1e-7] * 3 + [1e-6] * 3)


def _forward_jacobian(x: np.ndarray, *args: Any) -> np.ndarray:
    """Forward-difference Jacobian (what ``least_squares`` iterates with)."""
    xs = np.vstack([x, x + np.diag(_STEPS)])
    values = _batch_residuals(xs, *args)
    return ((values[1:] - values[0]) / _STEPS[:, None]).T


def _jacobian(x: np.ndarray, *args: Any) -> np.ndarray:
    """Central-difference Jacobian of the residuals, ``(n, 11)`` (for the covariance)."""
    steps = 10 * _STEPS
    xs = np.vstack([x + np.diag(steps), x - np.diag(steps)])
    values = _batch_residuals(xs, *args)
    return ((values[:N_PARAMETERS] - values[N_PARAMETERS:]) / (2 * steps[:, None])).T


def _starts(
    points: np.ndarray, options: FitOptions, upright: bool = False
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Initial parameters and reference rotations from the cloud's principal axes; with
    ``upright``, one more whose z is the world's vertical and x the cloud's widest
    horizontal axis (a box standing on its support: a view of two of its faces, an L, has
    its principal axes along the L's diagonal, and every fit from them ended tilted by
    35-40 degrees on the study's thin plank)."""
    centre = points.mean(axis=0)
    _, axes = np.linalg.eigh(np.cov((points - centre).T))
    axes = axes[:, ::-1]  # largest spread first
    references = []
    for k in range(options.starts):
        z = axes[:, k]
        x, y = (axes[:, j] for j in range(3) if j != k)
        reference = np.column_stack([x, y, z])
        if np.linalg.det(reference) < 0:
            reference[:, 0] *= -1
        references.append(reference)
    if upright:
        _, horizontal = np.linalg.eigh(np.cov((points - centre)[:, :2].T))
        x = np.array([*horizontal[:, -1], 0.0])
        vertical = np.array([0.0, 0.0, 1.0])
        references.append(np.column_stack([x, np.cross(vertical, x), vertical]))
    starts = []
    for reference in references:
        local = (points - centre) @ reference
        half = np.clip(np.ptp(local, axis=0) / 2, 2 * options.min_size, options.max_size / 2)
        middle = centre + reference @ ((local.max(axis=0) + local.min(axis=0)) / 2)
        x0 = np.concatenate([half, [0.5, 0.5], middle, np.zeros(3)])
        starts.append((x0, reference))
    return starts


def fit_superquadric(
    points: np.ndarray,
    options: FitOptions | None = None,
    silhouette: Silhouette | None = None,
    noise: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
    size_prior: tuple[np.ndarray, float, tuple[tuple[int, int], ...]] | None = None,
    solid: str | None = None,
    covariance: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
) -> SuperquadricFit:
    """Fit a superquadric to ``points`` [m] (world frame) by least squares.

    With a sensor ``noise`` model the fit is a weighted least squares one: each
    point's residual divided by its noise's standard deviation along the normal of the
    best start's surface (relative to their mean, so that residuals stay in metres). The depth noise
    varies tenfold between a surface seen face-on and one seen at grazing incidence, and
    the grazing points at the object's edges are those that fix its position across the
    view: unweighted, ``s^2`` (the average noise) understates their noise and the
    covariance is too small.

    Args:
        points: The object's points.
        options: Bounds, starts, covariance estimator.
        silhouette: The view's free space (:class:`Silhouette`); None: points alone.
        noise: ``noise(points, normals) -> sigma`` [m], the sensor noise's standard
            deviation along each unit normal (world frame), e.g.
            :func:`~openup_ompl.perception.noise.normal_sigma`; None: unweighted.
        size_prior: The scene's half-extents [m], how well they are known [m] (each
            fitted half-size is pulled to the one it best matches: without it a fit at
            high noise may grow away from the camera behind its own silhouette) and the
            pairs of half-sizes held equal (:class:`SizePrior`); None: the sizes free.
        solid: The solid the scene names (a key of
            :data:`~openup_ompl.perception.superquadric.SOLIDS`): its exponents are held
            at the solid's and each point's residual is its exact distance to it; None:
            the superquadric free (a mesh's first guess).
        covariance: ``covariance(points, normals) -> (n, 3, 3)`` [m^2], the sensor
            noise's covariance (world frame, e.g.
            :func:`~openup_ompl.perception.noise.noise_covariance`): the minimum found
            with ``noise``'s weights is refined with a round ``solid``'s points
            (:data:`~openup_ompl.perception.likelihood.ROUND`) measured by their
            Mahalanobis distance to it under their covariance at the best start's
            normals, scaled to the mean sigma along them (the maximum-likelihood
            residual, :mod:`~openup_ompl.perception.likelihood`), and the covariance is
            that of those residuals; None, or a box: the weighted Euclidean distance.

    Raises:
        TooFewPoints: Fewer points than twice the 11 parameters (fewer than 11 leaves the
            fit undetermined; a few more than 11 leave ``s^2`` meaningless).
        ConfigError: ``points`` not of shape ``(N, 3)``, or not finite, or at one place or
            on one line; an unknown ``solid``.

    Returns:
        The fit: the superquadric, its parameters' covariance and the residuals.
    """
    from scipy.optimize import least_squares

    options = options or FitOptions()
    points = checked_points(points)
    low, high = _bounds(options, solid)
    evaluations = 0

    def solve(x0: np.ndarray, reference: np.ndarray, budget: int, free: Any, *extra: Any) -> Any:
        nonlocal evaluations
        result = least_squares(
            _residuals,
            np.clip(x0, low + 1e-9, high - 1e-9),
            bounds=(low, high),
            args=(points, reference, free, *extra),
            x_scale=_X_SCALE,
            max_nfev=budget,
            method="trf",
            jac=_forward_jacobian,
            ftol=1e-7,
            xtol=1e-7,
        )
        evaluations += int(result.nfev)
        return result

    # A scene's box standing on its support (a face down): one start upright as well.
    upright = solid == "box" and silhouette is not None and silhouette.support is not None
    # A few steps on the points alone; the best start sets the weights and the prior's scale.
    trials = [
        (solve(x0, reference, options.trial_evaluations, None, None, None, solid), reference)
        for x0, reference in _starts(points, options, upright)
    ]
    first, reference = min(trials, key=lambda trial: float(trial[0].cost))
    normals = _world_normals(first.x, reference, points)  # close enough to the fit's
    weights, noises = _sensor(points, normals, noise, covariance if solid in ROUND else None)
    prior = None
    if size_prior is not None:
        scale = float(np.sqrt(np.mean(first.fun[: len(points)] ** 2)))  # their spread
        half, spread, ties = size_prior
        tie = math.sqrt(len(points))
        half = np.asarray(half, dtype=float)
        prior = SizePrior(half, spread, scale, tuple(ties), tie, solid == "cylinder")
    # Every start solved with the free space: the points alone may pick a wrong basin.
    budget = options.max_evaluations
    how = (silhouette, weights, prior, solid)
    finals = [(solve(t.x, r, budget, *how), r) for t, r in trials]
    result, reference = min(finals, key=lambda final: float(final[0].cost))
    hidden = None
    if solid is not None and silhouette is not None:
        # The faces the camera does not see, from the solved fit: its points measure none.
        sq = _split(result.x, reference)
        box = (sq.rotation[None], sq.position[None], sq.sizes[None])
        hidden = _hidden_faces(*box, silhouette.position, silhouette.max_incidence)[0]
        if solid == "box":
            hidden = hidden & ~_held_faces(sq.local(points), sq.sizes)
        result = solve(result.x, reference, budget, *how, hidden)
    if noises is not None:
        # The likelihood refines the minimum the weighted distance found: solving every
        # start with it, the LWA3 can seen from 75 degrees ended in a wrong one more often.
        how = (silhouette, None, prior, solid)
        result = solve(result.x, reference, budget, *how, hidden, noises)
    return _result(result.x, reference, points, (*how, hidden, noises), options, evaluations)


def _sensor(
    points: np.ndarray,
    normals: np.ndarray,
    noise: Callable[[np.ndarray, np.ndarray], np.ndarray] | None,
    covariance: Callable[[np.ndarray, np.ndarray], np.ndarray] | None,
) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The points' weights (their mean sigma along the ``normals`` over each one's) and
    their noise covariances scaled to that mean (the likelihood's residuals then read in
    metres; None without a ``covariance``, or with a zero one: no noise)."""
    weights = noises = None
    if noise is not None:
        sigma = noise(points, normals)
        weights = float(np.mean(sigma)) / sigma
    if covariance is not None:
        noises = covariance(points, normals)
        along = float(np.mean(np.sqrt(np.einsum("ni,nij,nj->n", normals, noises, normals))))
        noises = noises / along**2 if along > 0 else None
    return weights, noises


def _world_normals(x: np.ndarray, reference: np.ndarray, points: np.ndarray) -> np.ndarray:
    """The unit normals (world frame) of the superquadric ``x`` at the points."""
    sq = _split(x, reference)
    return np.asarray(_normals(sq.local(points), sq.sizes, *sq.exponents) @ sq.rotation.T)


def _bounds(options: FitOptions, solid: str | None) -> tuple[np.ndarray, np.ndarray]:
    """The parameters' bounds; a ``solid``'s exponents held at its own (the bounds must
    differ: by 1e-6)."""
    low = np.array([options.min_size] * 3 + [options.min_exponent] * 2 + [-np.inf] * 6)
    high = np.array([options.max_size] * 3 + [options.max_exponent] * 2 + [np.inf] * 6)
    if solid is not None:
        if solid not in SOLIDS:
            raise ConfigError("solid", solid, f"None or one of {sorted(SOLIDS)}")
        held = [options.min_exponent if e is None else e for e in SOLIDS[solid]]
        low[3:5], high[3:5] = held, np.add(held, 1e-6)
    return low, high


def _result(
    x: np.ndarray,
    reference: np.ndarray,
    points: np.ndarray,
    fitted: tuple[Any, ...],
    options: FitOptions,
    evaluations: int,
) -> SuperquadricFit:
    """The fit at its optimum ``x`` (about ``reference``; ``fitted``: the free space,
    weights, prior, solid, hidden faces and covariances it was fitted with), with its
    covariance (of the residuals as fitted: ``s^2`` is theirs)."""
    superquadric = _split(x, reference)
    # Re-linearise about the fitted orientation: the rotation block is then in its frame.
    x = x.copy()
    x[8:11] = 0.0
    silhouette, weights, prior = fitted[:3]
    args = (points, superquadric.rotation, *fitted)
    residuals = _residuals(x, *args)
    jacobian = _jacobian(x, *args)
    # A solid's exponents are its own, not estimated.
    held = [] if fitted[3] is None else list(range(EXPONENTS.start, EXPONENTS.stop))
    jacobian[:, held] = 0.0
    n = points.shape[0]
    rows = measurement_rows(residuals, n, 0 if silhouette is None else len(silhouette.samples))
    covariance, unobservable = parameter_covariance(
        jacobian[rows], residuals[rows], n, options.covariance, held
    )
    unweighted = residuals[:n] / weights if weights is not None else residuals[:n]
    if fitted[5] is not None:  # Mahalanobis: report the Euclidean distances
        unweighted = _points_distance(x[None], points, superquadric.rotation[None], *fitted[3:5])[0]
    return SuperquadricFit(
        superquadric=superquadric,
        covariance=covariance,
        residual_rms=float(np.sqrt(unweighted @ unweighted / (n - N_PARAMETERS))),
        mean_residual=float(np.mean(np.abs(unweighted))),
        points=n,
        evaluations=evaluations,
        unobservable=unobservable,
        jacobian=jacobian[rows],
        residuals=residuals[rows],
        kind=options.covariance,
        prior_rows=0 if prior is None else 3 + len(prior.ties),
        solid=fitted[3],
        hidden=fitted[4],
    )
