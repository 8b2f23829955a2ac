"""Superquadric fit of an object's point cloud, with the covariance of its pose.

The superquadric is Solina and Bajcsy's (F. Solina and R. Bajcsy, "Recovery of Parametric
Models from Range Images: The Case for Superquadrics with Global Deformations", IEEE
PAMI 12(2), 1990): in its own frame the inside-outside function

    F(x, y, z) = ((x/a1)^(2/e2) + (y/a2)^(2/e2))^(e2/e1) + (z/a3)^(2/e1)

is 1 on the surface, below 1 inside. Its 11 parameters are the half-sizes ``a1, a2, a3``
[m], the exponents ``e1`` (the profile along z) and ``e2`` (the cross-section in x-y),
the position ``t`` [m] and the orientation ``R`` (a rotation vector about a reference
rotation, in that reference's frame). A box is ``e1, e2 -> 0``, a cylinder along z is
``e1 -> 0, e2 = 1``, an ellipsoid ``e1 = e2 = 1``.

Each point's residual is its radial distance to the surface, ``|p| (1 - F(p)^(-e1/2))``
[m] (``p`` in the superquadric's frame; the surface point on the line from the centre
through ``p`` is ``p F^(-e1/2)``): a distance in metres, so that the residual variance is
comparable to the sensor's noise, unlike Solina's volume-weighted ``F^e1 - 1``.

``scipy.optimize.least_squares`` (trust-region reflective, exponents and sizes bounded)
is started from the cloud's principal axes, once with each principal axis as the
superquadric's z axis, and the lowest cost wins: the cylinder is only representable with
its axis along z, and a partial view's principal axes are not ordered by the object's.

The covariance of the 11 parameters is the Gauss-Newton one, ``s^2 (J^T J)^-1``, ``s^2 =
sum r^2 / (n - 11)``, with ``J`` the residuals' Jacobian at the optimum (rotation
re-linearised about the fitted orientation, so the rotation block is in the fitted frame)
— the ``classic`` estimator — or its heteroscedasticity-consistent sandwich form (see
:class:`FitOptions`). Directions of ``J^T J`` with no information (a cylinder's yaw about
its axis, the sizes of an unseen side...) are given by a pseudo-inverse and listed in
``unobservable``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from openup_ompl.exceptions import ConfigError, TooFewPoints

__all__ = [
    "PARAMETERS",
    "FitOptions",
    "Silhouette",
    "Superquadric",
    "SuperquadricFit",
    "fit_superquadric",
    "rotation_from_vector",
]

#: The fit's parameters, in the order of :attr:`SuperquadricFit.covariance`.
PARAMETERS = ("a1", "a2", "a3", "e1", "e2", "x", "y", "z", "rx", "ry", "rz")
N_PARAMETERS = len(PARAMETERS)
POSITION = slice(5, 8)
ROTATION = slice(8, 11)
COVARIANCES = ("classic", "sandwich")


@dataclass(frozen=True)
class FitOptions:
    """The superquadric fit's settings.

    Attributes:
        min_exponent: Lower bound of ``e1``, ``e2`` (sharper edges are not representable;
            0.1 rounds a 3 cm edge by under 1 mm).
        max_exponent: Upper bound of ``e1``, ``e2`` (2: the superquadric stays convex).
        min_size: Lower bound of the half-sizes [m].
        max_size: Upper bound of the half-sizes [m].
        starts: Principal axes tried as the superquadric's z axis (1 to 3).
        max_evaluations: Residual evaluations per start.
        covariance: ``"classic"``: ``s^2 (J^T J)^-1``; ``"sandwich"``: ``(J^T J)^-1 J^T
            diag(r^2) J (J^T J)^-1 n / (n - 11)`` (White's estimator: the same when every
            residual has one variance, right when they differ, as the depth noise does
            with depth and incidence).
    """

    min_exponent: float = 0.1
    max_exponent: float = 2.0
    min_size: float = 0.002  # [m]
    max_size: float = 1.0  # [m]
    starts: int = 3
    max_evaluations: int = 400
    covariance: str = "classic"

    def __post_init__(self) -> None:
        if not 0.01 <= self.min_exponent < self.max_exponent <= 4.0:
            raise ConfigError(
                "fit.min_exponent, max_exponent",
                (self.min_exponent, self.max_exponent),
                "0.01 <= min_exponent < max_exponent <= 4",
            )
        if not 0 < self.min_size < self.max_size:
            raise ConfigError(
                "fit.min_size, max_size", (self.min_size, self.max_size), "0 < min < max [m]"
            )
        if self.starts not in (1, 2, 3):
            raise ConfigError("fit.starts", self.starts, "1, 2 or 3")
        if self.max_evaluations < 10:
            raise ConfigError("fit.max_evaluations", self.max_evaluations, "at least 10")
        if self.covariance not in COVARIANCES:
            raise ConfigError("fit.covariance", self.covariance, f"one of {COVARIANCES}")


def rotation_from_vector(vector: np.ndarray) -> np.ndarray:
    """Rodrigues' formula: the rotation matrix of a rotation vector [rad]."""
    angle = float(np.linalg.norm(vector))
    if angle < 1e-12:
        k = np.array(vector, dtype=float)
        return np.eye(3) + np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    k = np.asarray(vector, dtype=float) / angle
    skew = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * skew + (1 - math.cos(angle)) * skew @ skew


def _log_inside_outside(local: np.ndarray, sizes: np.ndarray, e1: float, e2: float) -> np.ndarray:
    """``log F`` of points in the superquadric's frame (in logs: the powers overflow)."""
    logs = np.log(np.abs(local) / sizes + 1e-300)
    xy = np.logaddexp(logs[:, 0] * (2 / e2), logs[:, 1] * (2 / e2)) * (e2 / e1)
    return np.logaddexp(xy, logs[:, 2] * (2 / e1))


@dataclass(frozen=True)
class Superquadric:
    """A superquadric in the world frame.

    Attributes:
        sizes: Half-sizes ``a1, a2, a3`` [m] along its frame's x, y, z.
        exponents: ``e1`` (profile along z), ``e2`` (x-y cross-section).
        position: Centre [m], world frame.
        rotation: Its frame in the world frame (3 x 3).
    """

    sizes: np.ndarray
    exponents: np.ndarray
    position: np.ndarray
    rotation: np.ndarray

    def local(self, points: np.ndarray) -> np.ndarray:
        """World points [m] in the superquadric's frame."""
        return (np.asarray(points, dtype=float) - self.position) @ self.rotation

    def inside_outside(self, points: np.ndarray) -> np.ndarray:
        """Solina-Bajcsy ``F`` at world points (1 on the surface)."""
        e1, e2 = self.exponents
        return np.exp(_log_inside_outside(self.local(points), self.sizes, e1, e2))

    def radial_distance(self, points: np.ndarray) -> np.ndarray:
        """Signed radial distance [m] of world points to the surface (positive outside)."""
        local = self.local(points)
        e1, e2 = self.exponents
        log_f = _log_inside_outside(local, self.sizes, e1, e2)
        return np.linalg.norm(local, axis=1) * (1 - np.exp(-e1 / 2 * log_f))

    def surface(self, n: int = 24) -> np.ndarray:
        """``(n, 2n, 3)`` world points on the surface (the parametric form), for figures."""
        e1, e2 = self.exponents
        local = _surface_local(self.sizes, e1, e2, _angles(n, 2 * n))
        return (local @ self.rotation.T + self.position).reshape(n, 2 * n, 3)


def _angles(n_eta: int, n_omega: int) -> np.ndarray:
    """``(n_eta * n_omega, 4)``: cos and sin of the latitude eta and the longitude omega."""
    eta, omega = np.meshgrid(
        np.linspace(-math.pi / 2, math.pi / 2, n_eta),
        np.linspace(-math.pi, math.pi, n_omega),
        indexing="ij",
    )
    return np.column_stack(
        [np.cos(eta).ravel(), np.sin(eta).ravel(), np.cos(omega).ravel(), np.sin(omega).ravel()]
    )


def _surface_local(sizes: np.ndarray, e1: float, e2: float, angles: np.ndarray) -> np.ndarray:
    """Surface points of the parametric superquadric in its own frame, ``(m, 3)``."""

    def power(x: np.ndarray, e: float) -> np.ndarray:
        return np.sign(x) * np.abs(x) ** e

    ring = power(angles[:, 0], e1)
    return np.column_stack(
        [
            sizes[0] * ring * power(angles[:, 2], e2),
            sizes[1] * ring * power(angles[:, 3], e2),
            sizes[2] * power(angles[:, 1], e1),
        ]
    )


@dataclass(frozen=True)
class Silhouette:
    """Free space seen by the camera: where the object may not project.

    A depth camera also sees past the object: a pixel that saw the table or the wall
    behind says the object is not in front of it. Without this a partial view leaves the
    unseen side free (a can's visible front half fits an ellipse reaching centimetres
    behind it equally well). Each surface sample of the superquadric that projects onto
    such a pixel adds a residual: its image distance to the allowed region (the object's
    pixels and pixels of occluders in front of it) beyond half a pixel, in metres at its
    depth.

    Attributes:
        distance: ``(H, W)`` pixel distance to the allowed region (0 inside it).
        position: Camera position [m], world frame.
        rotation: Camera frame (x right, y down, z forward) in the world frame.
        intrinsics: ``(fx, fy, cx, cy)`` [px].
        samples: Surface sample angles (:func:`_angles`).
    """

    distance: np.ndarray
    position: np.ndarray
    rotation: np.ndarray
    intrinsics: tuple[float, float, float, float]
    samples: np.ndarray

    @classmethod
    def from_view(
        cls,
        object_mask: np.ndarray,
        occluder_mask: np.ndarray,
        position: np.ndarray,
        rotation: np.ndarray,
        intrinsics: tuple[float, float, float, float],
        samples: tuple[int, int] = (12, 24),
    ) -> Silhouette:
        """From ``(H, W)`` masks of the object's pixels and of pixels whose hit is in
        front of the object (where it may hide)."""
        from scipy.ndimage import distance_transform_edt

        allowed = object_mask | occluder_mask
        distance = distance_transform_edt(~allowed)
        return cls(
            np.asarray(distance, dtype=float), position, rotation, intrinsics, _angles(*samples)
        )

    def excess(self, world: np.ndarray) -> np.ndarray:
        """Each world point's image distance [m] beyond the allowed region."""
        from scipy.ndimage import map_coordinates

        fx, fy, cx, cy = self.intrinsics
        camera = (world - self.position) @ self.rotation
        z = np.maximum(camera[:, 2], 1e-3)
        column = fx * camera[:, 0] / z + cx - 0.5
        row = fy * camera[:, 1] / z + cy - 0.5
        pixels = map_coordinates(self.distance, [row, column], order=1, mode="nearest")
        return np.maximum(pixels - 0.5, 0.0) * z / fx


@dataclass(frozen=True)
class SuperquadricFit:
    """A fitted superquadric and the uncertainty of its parameters.

    Attributes:
        superquadric: The fit.
        covariance: ``(11, 11)`` covariance of :data:`PARAMETERS` (rotation in the fitted
            frame) [m, rad].
        residual_rms: ``s``, the residuals' standard deviation [m] (``n - 11`` dof).
        mean_residual: Mean absolute radial distance [m] of the points to the fit (the
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


def _split(x: np.ndarray, reference: np.ndarray) -> Superquadric:
    return Superquadric(
        sizes=x[0:3].copy(),
        exponents=x[3:5].copy(),
        position=x[5:8].copy(),
        rotation=reference @ rotation_from_vector(x[8:11]),
    )


def _residuals(
    x: np.ndarray,
    points: np.ndarray,
    reference: np.ndarray,
    silhouette: Silhouette | None = None,
) -> np.ndarray:
    rotation = reference @ rotation_from_vector(x[8:11])
    local = (points - x[5:8]) @ rotation
    log_f = _log_inside_outside(local, x[0:3], x[3], x[4])
    radial = np.linalg.norm(local, axis=1) * (1 - np.exp(-x[3] / 2 * log_f))
    if silhouette is None:
        return radial
    surface = _surface_local(x[0:3], x[3], x[4], silhouette.samples) @ rotation.T + x[5:8]
    return np.concatenate([radial, silhouette.excess(surface)])


def _jacobian(
    x: np.ndarray, points: np.ndarray, reference: np.ndarray, silhouette: Silhouette | None
) -> np.ndarray:
    """Central-difference Jacobian of the residuals, ``(n, 11)``."""
    steps = np.array([1e-6] * 3 + [1e-5] * 2 + [1e-6] * 3 + [1e-5] * 3)
    jacobian = np.empty((_residuals(x, points, reference, silhouette).size, N_PARAMETERS))
    for j, step in enumerate(steps):
        forward, backward = x.copy(), x.copy()
        forward[j] += step
        backward[j] -= step
        jacobian[:, j] = (
            _residuals(forward, points, reference, silhouette)
            - _residuals(backward, points, reference, silhouette)
        ) / (2 * step)
    return jacobian


def _starts(points: np.ndarray, options: FitOptions) -> list[tuple[np.ndarray, np.ndarray]]:
    """Initial parameters and reference rotations from the cloud's principal axes."""
    centre = points.mean(axis=0)
    _, axes = np.linalg.eigh(np.cov((points - centre).T))
    axes = axes[:, ::-1]  # largest spread first
    starts = []
    for k in range(options.starts):
        z = axes[:, k]
        x, y = (axes[:, j] for j in range(3) if j != k)
        reference = np.column_stack([x, y, z])
        if np.linalg.det(reference) < 0:
            reference[:, 0] *= -1
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
) -> SuperquadricFit:
    """Fit a superquadric to ``points`` [m] (world frame) by least squares.

    Args:
        points: The object's points.
        options: Bounds, starts, covariance estimator.
        silhouette: The view's free space (:class:`Silhouette`); None: points alone.

    Raises:
        TooFewPoints: Fewer points than twice the 11 parameters (fewer than 11 leaves the
            fit undetermined; a few more than 11 leave ``s^2`` meaningless).
    """
    from scipy.optimize import least_squares

    options = options or FitOptions()
    points = np.asarray(points, dtype=float)
    needed = 2 * N_PARAMETERS
    if points.ndim != 2 or points.shape[1] != 3 or points.shape[0] < needed:
        raise TooFewPoints(int(points.shape[0]) if points.ndim == 2 else 0, needed)
    if not np.all(np.isfinite(points)):
        raise ConfigError("points", "non-finite values", "finite [x, y, z] rows [m]")
    low = np.array([options.min_size] * 3 + [options.min_exponent] * 2 + [-np.inf] * 6)
    high = np.array([options.max_size] * 3 + [options.max_exponent] * 2 + [np.inf] * 6)
    best = None
    evaluations = 0
    for x0, reference in _starts(points, options):
        result = least_squares(
            _residuals,
            np.clip(x0, low + 1e-9, high - 1e-9),
            bounds=(low, high),
            args=(points, reference, silhouette),
            x_scale=np.array([0.01] * 3 + [0.1] * 2 + [0.01] * 3 + [0.1] * 3),
            max_nfev=options.max_evaluations,
            method="trf",
        )
        evaluations += int(result.nfev)
        if best is None or result.cost < best[0].cost:
            best = (result, reference)
    assert best is not None
    result, reference = best
    superquadric = _split(result.x, reference)
    # Re-linearise about the fitted orientation: the rotation block is then in its frame.
    x = result.x.copy()
    x[8:11] = 0.0
    residuals = _residuals(x, points, superquadric.rotation, silhouette)
    jacobian = _jacobian(x, points, superquadric.rotation, silhouette)
    n = points.shape[0]
    variance = float(residuals[:n] @ residuals[:n] / (n - N_PARAMETERS))
    covariance, unobservable = _covariance(jacobian, residuals, variance, options.covariance)
    return SuperquadricFit(
        superquadric=superquadric,
        covariance=covariance,
        residual_rms=float(np.sqrt(residuals[:n] @ residuals[:n] / (n - N_PARAMETERS))),
        mean_residual=float(np.mean(np.abs(residuals[:n]))),
        points=n,
        evaluations=evaluations,
        unobservable=unobservable,
    )


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
