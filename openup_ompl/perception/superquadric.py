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

Each point's residual is its first-order (Taubin) distance to the surface, ``(G - 1) /
|grad G|`` [m] with ``G = F^(e1/2)`` (``G`` grows linearly along every ray from the centre,
so this is the distance along the surface normal up to second order: exactly ``rho - a``
on a cylinder's side). Solina's volume-weighted ``F^e1 - 1`` and the radial distance
``|p| (1 - F^(-e1/2))`` both grow with the point's distance from the centre: on a partial
view they pull the centre away from the seen side (measured: 12 mm on the shipped can,
for 1.6 mm of noise), while this residual does not.

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

``J`` holds the points' rows and the support's (an equality: the object stands on it), not
the free space's (:class:`Silhouette`): those are an inequality, zero inside the one-pixel
band and a penalty beyond it, that bounds the estimate without measuring it. Counted as
measurements with the points' variance, the few samples a fit pushes past the band (those
fits that grew away from the camera, or squared off a round section) made their
covariance millimetres where the error was centimetres (LWA3 can at noise 4: 50 % inside
the 2-sigma ellipse with them, 68 % without; box 74 and 88 %; thin stick 61 and 87 %).
Without them the covariance is that of the points and the support alone, which bounds the
bounded estimate's: conservative where only the outline fixes a side (the box's face seen
too obliquely to measure: its lateral sigma 2.2 mm, median, for an error of 1.0 mm sd).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from openup_ompl._toml import is_integer, is_number
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
#: The least RMS spread [m] of a fitted cloud about its mean in its second direction:
#: 0.1 mm, a hundredth of the sensor noise's size.
MIN_SPREAD = 1e-4
POSITION = slice(5, 8)
ROTATION = slice(8, 11)
COVARIANCES = ("classic", "sandwich")


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
        trial_evaluations: Residual evaluations of each start before the lowest-cost one
            is solved to convergence.
        max_evaluations: Residual evaluations of that solve.
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


def _distance(local: np.ndarray, sizes: np.ndarray, e1: Any, e2: Any) -> np.ndarray:
    """Signed first-order distance [m] ``(G - 1) / |grad G|``, ``G = F^(e1/2)``.

    With ``l_i = (2/e2) log|x_i/a_i|``, ``A = (e2/e1) logaddexp(l_1, l_2)``, ``B = (2/e1)
    log|z/a_3|``: ``grad G = G (s_A s_1 / x, s_A s_2 / y, s_B / z)``, ``s`` the softmax
    weights of ``(A, B)`` and of ``(l_1, l_2)``. Broadcasts over leading axes (a batch of
    parameter sets: ``local (k, n, 3)``, ``sizes (k, 1, 3)``, ``e1, e2 (k, 1)``).
    """
    gradient, log_f = _gradient(local, sizes, e1, e2)
    g = np.exp(e1 / 2 * log_f)
    return (g - 1) / (g * np.linalg.norm(gradient, axis=-1) + 1e-300)


def _gradient(
    local: np.ndarray, sizes: np.ndarray, e1: Any, e2: Any
) -> tuple[np.ndarray, np.ndarray]:
    """``grad G / G`` (signed) and ``log F`` at points in the superquadric's frame."""
    logs = np.log(np.abs(local) / sizes + 1e-300)
    l1, l2 = logs[..., 0] * (2 / e2), logs[..., 1] * (2 / e2)
    xy = np.logaddexp(l1, l2)
    big_a, big_b = xy * (e2 / e1), logs[..., 2] * (2 / e1)
    log_f = np.logaddexp(big_a, big_b)
    safe = np.where(local >= 0, 1.0, -1.0) * np.maximum(np.abs(local), 1e-300)
    gradient = np.stack(
        [
            np.exp(big_a - log_f + l1 - xy) / safe[..., 0],
            np.exp(big_a - log_f + l2 - xy) / safe[..., 1],
            np.exp(big_b - log_f) / safe[..., 2],
        ],
        axis=-1,
    )
    return gradient, log_f


def _normals(local: np.ndarray, sizes: np.ndarray, e1: float, e2: float) -> np.ndarray:
    """Unit outward normals (``grad G`` directions) at points in the superquadric's frame."""
    gradient, _ = _gradient(local, sizes, e1, e2)
    return gradient / np.linalg.norm(gradient, axis=-1, keepdims=True)


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

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Signed first-order distance [m] of world points to the surface (positive
        outside; see the module docstring)."""
        e1, e2 = self.exponents
        return _distance(self.local(points), self.sizes, e1, e2)

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


def _surface_local(sizes: np.ndarray, e1: Any, e2: Any, angles: np.ndarray) -> np.ndarray:
    """Surface points of the parametric superquadric in its own frame, ``(..., m, 3)``
    (broadcasts like :func:`_distance`)."""

    def power(x: np.ndarray, e: Any) -> np.ndarray:
        return np.sign(x) * np.abs(x) ** e

    ring = power(angles[:, 0], e1)
    return np.stack(
        [
            sizes[..., 0] * ring * power(angles[:, 2], e2),
            sizes[..., 1] * ring * power(angles[:, 3], e2),
            sizes[..., 2] * power(angles[:, 1], e1),
        ],
        axis=-1,
    )


@dataclass(frozen=True)
class Silhouette:
    """Free space seen by the camera: where the object may not project.

    A depth camera also sees past the object: a pixel that saw the table or the wall
    behind says the object is not in front of it. Without this a partial view leaves the
    unseen side free (a can's visible front half fits an ellipse reaching centimetres
    behind it equally well). Each surface sample of the superquadric that projects onto
    such a pixel adds a residual: its image distance to the allowed region (the object's
    pixels and pixels of occluders in front of it) beyond one pixel (the object's edge lies
    somewhere between its last pixel centre and the next), in metres at its depth.

    The camera cannot see through the table the object stands on: a sample below the
    table's top hides behind it, and a view from above let the fitted can grow through
    the table (16 cm at the Panda scene's elevation 60, seed 5), or float 1 cm above it
    (the top face seen, the bottom hidden). With the ``support``'s height each sample
    below it adds its depth below it, and one residual, weighted as all the points
    together, holds the lowest sample on it: the object stands on its support.

    Attributes:
        distance: ``(H, W)`` pixel distance to the allowed region (0 inside it).
        position: Camera position [m], world frame.
        rotation: Camera frame (x right, y down, z forward) in the world frame.
        intrinsics: ``(fx, fy, cx, cy)`` [px].
        samples: Surface sample angles (:func:`_angles`).
        support: Height [m, world z] of the surface the object stands on (None: unknown).
    """

    distance: np.ndarray
    position: np.ndarray
    rotation: np.ndarray
    intrinsics: tuple[float, float, float, float]
    samples: np.ndarray
    support: float | None = None

    @classmethod
    def from_view(
        cls,
        object_mask: np.ndarray,
        occluder_mask: np.ndarray,
        position: np.ndarray,
        rotation: np.ndarray,
        intrinsics: tuple[float, float, float, float],
        samples: tuple[int, int] = (10, 20),
        support: float | None = None,
    ) -> Silhouette:
        """From ``(H, W)`` masks of the object's pixels and of pixels whose hit is in
        front of the object (where it may hide), and the ``support``'s height."""
        from scipy.ndimage import distance_transform_edt

        allowed = object_mask | occluder_mask
        distance = distance_transform_edt(~allowed)
        return cls(
            np.asarray(distance, dtype=float),
            position,
            rotation,
            intrinsics,
            _angles(*samples),
            support,
        )

    def excess(self, world: np.ndarray) -> np.ndarray:
        """Each world point's image distance [m] beyond the allowed region, plus its depth
        below the :attr:`support`."""
        from scipy.ndimage import map_coordinates

        fx, fy, cx, cy = self.intrinsics
        shape = world.shape[:-1]
        camera = (world.reshape(-1, 3) - self.position) @ self.rotation
        z = np.maximum(camera[:, 2], 1e-3)
        column = fx * camera[:, 0] / z + cx - 0.5
        row = fy * camera[:, 1] / z + cy - 0.5
        pixels = map_coordinates(self.distance, [row, column], order=1, mode="nearest")
        excess = (np.maximum(pixels - 1.0, 0.0) * z / fx).reshape(shape)
        if self.support is None:
            return excess
        return excess + np.maximum(self.support - world[..., 2], 0.0)


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


def _split(x: np.ndarray, reference: np.ndarray) -> Superquadric:
    return Superquadric(
        sizes=x[0:3].copy(),
        exponents=x[3:5].copy(),
        position=x[5:8].copy(),
        rotation=reference @ rotation_from_vector(x[8:11]),
    )


def _rotations(vectors: np.ndarray) -> np.ndarray:
    """Rodrigues' formula for a batch of rotation vectors ``(k, 3)`` -> ``(k, 3, 3)``."""
    angle = np.linalg.norm(vectors, axis=1)
    small = angle < 1e-12
    axis = vectors / np.where(small, 1.0, angle)[:, None]
    skew = np.zeros((vectors.shape[0], 3, 3))
    skew[:, 0, 1], skew[:, 0, 2], skew[:, 1, 2] = -axis[:, 2], axis[:, 1], -axis[:, 0]
    skew -= skew.transpose(0, 2, 1)
    sine = np.where(small, 1.0, np.sin(angle))[:, None, None]
    cosine = np.where(small, 0.0, 1 - np.cos(angle))[:, None, None]
    rotations = np.eye(3) + sine * skew + cosine * skew @ skew
    # Tiny angles: first order, I + [v]x (the axis above is then v itself).
    rotations[small] = np.eye(3) + skew[small]
    return rotations


def _batch_residuals(
    xs: np.ndarray,
    points: np.ndarray,
    reference: np.ndarray,
    silhouette: Silhouette | None = None,
    weights: np.ndarray | None = None,
) -> np.ndarray:
    """Residuals of ``k`` parameter sets at once, ``(k, n [+ m [+ 1]])`` (the points, the
    silhouette's samples, the resting on the support): one vectorised pass for a whole
    finite-difference Jacobian (12 sets cost about two single evaluations)."""
    rotations = reference @ _rotations(xs[:, 8:11])
    local = (points[None] - xs[:, None, 5:8]) @ rotations
    sizes, e1, e2 = xs[:, None, 0:3], xs[:, 3:4], xs[:, 4:5]
    distance = _distance(local, sizes, e1, e2)
    if weights is not None:
        distance = distance * weights
    if silhouette is None:
        return distance
    surface = _surface_local(sizes, e1, e2, silhouette.samples)
    world = surface @ rotations.transpose(0, 2, 1) + xs[:, None, 5:8]
    excess = silhouette.excess(world)
    if silhouette.support is None:
        return np.concatenate([distance, excess], axis=1)
    # Standing on it: the lowest sample on the support, as strongly as the points weigh.
    resting = (world[..., 2].min(axis=1) - silhouette.support) * math.sqrt(points.shape[0])
    return np.concatenate([distance, excess, resting[:, None]], axis=1)


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
    noise: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
) -> SuperquadricFit:
    """Fit a superquadric to ``points`` [m] (world frame) by least squares.

    With a sensor ``noise`` model the fit is a weighted least squares one: each
    point's residual divided by its noise's standard deviation along the normal of the
    best start's surface (relative to their mean, so that residuals stay in metres). The depth noise
    varies tenfold between a surface seen face-on and one seen at grazing incidence, and
    the grazing points at the object's edges are those that fix its position across the
    view: unweighted, ``s^2`` (the average noise) understates their noise and the
    covariance is too small (measured: 85 % instead of 95 % inside the 2-sigma ellipse).

    Args:
        points: The object's points.
        options: Bounds, starts, covariance estimator.
        silhouette: The view's free space (:class:`Silhouette`); None: points alone.
        noise: ``noise(points, normals) -> sigma`` [m], the sensor noise's standard
            deviation along each unit normal (world frame), e.g.
            :func:`~openup_ompl.perception.noise.normal_sigma`; None: unweighted.

    Raises:
        TooFewPoints: Fewer points than twice the 11 parameters (fewer than 11 leaves the
            fit undetermined; a few more than 11 leave ``s^2`` meaningless).
        ConfigError: ``points`` not of shape ``(N, 3)``, or not finite, or at one place or
            on one line.
    """
    from scipy.optimize import least_squares

    options = options or FitOptions()
    points = np.asarray(points, dtype=float)
    needed = 2 * N_PARAMETERS
    if points.ndim != 2 or points.shape[1] != 3:
        raise ConfigError("points", f"an array of shape {points.shape}", "(N, 3) rows [x, y, z]")
    if points.shape[0] < needed:
        raise TooFewPoints(int(points.shape[0]), needed)
    if not np.all(np.isfinite(points)):
        raise ConfigError("points", "non-finite values", "finite [x, y, z] rows [m]")
    # Points at one place or on one line leave the surface undetermined, and the fit
    # then finds a perfect one: a zero covariance, "certain" from no information.
    spread = np.linalg.svd(points - points.mean(axis=0), compute_uv=False) / math.sqrt(
        points.shape[0]
    )
    if spread[1] < MIN_SPREAD:
        raise ConfigError(
            "points",
            f"{points.shape[0]} points at one place or on a line (spread {spread[1]:.2g} m)",
            f"points spread over a surface, more than {MIN_SPREAD:g} m in two directions",
        )
    low = np.array([options.min_size] * 3 + [options.min_exponent] * 2 + [-np.inf] * 6)
    high = np.array([options.max_size] * 3 + [options.max_exponent] * 2 + [np.inf] * 6)
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

    # Every start gets a few steps on the points alone; the most promising is solved to
    # convergence, with the free space.
    trials = [
        (solve(x0, reference, options.trial_evaluations, None), reference)
        for x0, reference in _starts(points, options)
    ]
    first, reference = min(trials, key=lambda trial: float(trial[0].cost))
    weights = None
    if noise is not None:
        # Weights from the best start's surface: its normals are already close enough.
        fitted = _split(first.x, reference)
        local = fitted.local(points)
        normals = _normals(local, fitted.sizes, *fitted.exponents) @ fitted.rotation.T
        sigma = noise(points, normals)
        weights = float(np.mean(sigma)) / sigma
    result = solve(first.x, reference, options.max_evaluations, silhouette, weights)
    superquadric = _split(result.x, reference)
    # Re-linearise about the fitted orientation: the rotation block is then in its frame.
    x = result.x.copy()
    x[8:11] = 0.0
    args = (points, superquadric.rotation, silhouette, weights)
    residuals = _residuals(x, *args)
    jacobian = _jacobian(x, *args)
    n = points.shape[0]
    variance = float(residuals[:n] @ residuals[:n] / (n - N_PARAMETERS))
    # The points and the support measure; the free space only bounds (module docstring).
    rows = np.r_[0:n, n + _free_space_rows(silhouette) : residuals.shape[0]]
    covariance, unobservable = _covariance(
        jacobian[rows], residuals[rows], variance, options.covariance
    )
    unweighted = residuals[:n] / weights if weights is not None else residuals[:n]
    return SuperquadricFit(
        superquadric=superquadric,
        covariance=covariance,
        residual_rms=float(np.sqrt(unweighted @ unweighted / (n - N_PARAMETERS))),
        mean_residual=float(np.mean(np.abs(unweighted))),
        points=n,
        evaluations=evaluations,
        unobservable=unobservable,
    )


def _free_space_rows(silhouette: Silhouette | None) -> int:
    """How many residuals after the points are the free space's (:meth:`Silhouette.excess`
    of each surface sample)."""
    return 0 if silhouette is None else int(silhouette.samples.shape[0])


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
