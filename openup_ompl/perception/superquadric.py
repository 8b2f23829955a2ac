"""Solina and Bajcsy's superquadric: its inside-outside function, surface and distance.

The superquadric is Solina and Bajcsy's (F. Solina and R. Bajcsy, "Recovery of Parametric
Models from Range Images: The Case for Superquadrics with Global Deformations", IEEE
PAMI 12(2), 1990): in its own frame the inside-outside function

    F(x, y, z) = ((x/a1)^(2/e2) + (y/a2)^(2/e2))^(e2/e1) + (z/a3)^(2/e1)

is 1 on the surface, below 1 inside. Its 11 parameters are the half-sizes ``a1, a2, a3``
[m], the exponents ``e1`` (the profile along z) and ``e2`` (the cross-section in x-y),
the position ``t`` [m] and the orientation ``R`` (a rotation vector about a reference
rotation, in that reference's frame). A box is ``e1, e2 -> 0``, a cylinder along z is
``e1 -> 0, e2 = 1``, an ellipsoid ``e1 = e2 = 1``.

The fit lives in :mod:`~openup_ompl.perception.fit`, the covariance of its parameters in
:mod:`~openup_ompl.perception.covariance` (both re-exported here).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from openup_ompl.exceptions import ConfigError, TooFewPoints

__all__ = [
    "N_PARAMETERS",
    "PARAMETERS",
    "Superquadric",
    "checked_points",
    "rotation_from_vector",
]

#: The fit's parameters, in the order of :attr:`SuperquadricFit.covariance`.
PARAMETERS = ("a1", "a2", "a3", "e1", "e2", "x", "y", "z", "rx", "ry", "rz")
N_PARAMETERS = len(PARAMETERS)
EXPONENTS = slice(3, 5)
POSITION = slice(5, 8)
ROTATION = slice(8, 11)


def rotation_from_vector(vector: np.ndarray) -> np.ndarray:
    """Rodrigues' formula: the rotation matrix of a rotation vector.

    Args:
        vector: Rotation vector (axis times angle [rad]), shape ``(3,)``.

    Returns:
        The rotation matrix, shape ``(3, 3)`` (first order below an angle of 1e-12 rad).
    """
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


#: The solids a scene names whose surface the fit measures exactly
#: (:func:`_solid_distance`), and their superquadric exponents ``(e1, e2)`` (``None``: the
#: fit's sharpest, ``FitOptions.min_exponent``).
SOLIDS: dict[str, tuple[float | None, float | None]] = {
    "box": (None, None),
    "cylinder": (None, 1.0),
    "sphere": (1.0, 1.0),
}


def _hidden_faces(
    rotations: np.ndarray,
    positions: np.ndarray,
    sizes: np.ndarray,
    camera: np.ndarray,
    max_incidence: float,
) -> np.ndarray:
    """Which faces of boxes (``+x, -x, +y, -y, +z, -z`` of their frames) a camera at
    ``camera`` [m] sees beyond ``max_incidence`` [deg] at their centres, or from behind:
    the sensor returns no point from them.

    Args:
        rotations: ``(k, 3, 3)`` frames in the world.
        positions: ``(k, 3)`` centres [m], world frame.
        sizes: ``(k, 3)`` half-sizes [m].
        camera: The camera's position [m], world frame.
        max_incidence: The sensor's grazing limit [deg].

    Returns:
        ``(k, 6)`` booleans, True: hidden.
    """
    axes = np.repeat(rotations.transpose(0, 2, 1), 2, axis=1)  # (k, 6, 3): x, x, y, y...
    normals = axes * np.array([1.0, -1.0] * 3)[None, :, None]
    centres = positions[:, None, :] + normals * np.repeat(sizes, 2, axis=1)[..., None]
    rays = centres - np.asarray(camera, dtype=float)
    cosine = -np.sum(normals * rays, axis=-1) / np.linalg.norm(rays, axis=-1)
    return np.asarray(cosine < math.cos(math.radians(max_incidence)))


#: A box's face that holds at least this share of the points is seen whatever its
#: incidence at its centre (:func:`_held_faces`).
SEEN_SHARE = 0.15


def _held_faces(local: np.ndarray, sizes: np.ndarray) -> np.ndarray:
    """Which faces of a box (``+x, -x, +y, -y, +z, -z``) hold at least :data:`SEEN_SHARE`
    of the points (each point counted on the face it lies nearest to, in the box's frame):
    the sensor returned them, so the face is seen. A face near the grazing limit at its
    centre is seen over part of it (the clutter box's side held 41 of 235 points and was
    judged hidden: the fit tilted 17 degrees, 11.9 mm off); the few points noise carries
    across an edge stay under the share (up to 10 % on the study's plank).

    Args:
        local: ``(n, 3)`` points [m] in the box's frame.
        sizes: ``(3,)`` half-sizes [m].

    Returns:
        ``(6,)`` booleans, True: the face holds the share.
    """
    excess = np.stack([local - sizes, -local - sizes], axis=-1).reshape(len(local), 6)
    counts = np.bincount(np.argmax(excess, axis=1), minlength=6)
    return np.asarray(counts >= SEEN_SHARE * len(local))


def _solid_distance(
    local: np.ndarray, sizes: np.ndarray, solid: str, hidden: np.ndarray | None = None
) -> np.ndarray:
    """Signed Euclidean distance [m] of points (the superquadric's frame) to the solid of
    its half-sizes: a box, a cylinder about z (radius the mean of ``a1, a2``) or a ball
    (radius the mean of the three). Exact inside and out: ``|max(q, 0)| + min(max_i q_i,
    0)``, ``q`` the point's excess over each half-extent. The superquadric of the sharpest
    exponent rounds a box's edge over a few per cent of its half side, and a point of a
    face near the edge lies up to a millimetre outside it: the fit grew the box's sizes by
    1-2 mm into the outline's pixel (at no noise). The ``hidden`` faces (``(..., 6)``,
    :func:`_hidden_faces`; a cylinder's ends are its ``z`` faces) are left out, as if the
    solid ran on behind them: the sensor gives no point on them, and a point the noise
    carried across an edge onto one measured it by chance (their number jumped between
    seeds). Broadcasts like :func:`_distance`."""
    if solid == "sphere":
        return np.asarray(np.linalg.norm(local, axis=-1) - sizes.mean(axis=-1))
    faces = np.stack([local - sizes, -local - sizes], axis=-1)  # (..., 3, 2): +, - sides
    if hidden is not None:
        faces = np.where(hidden.reshape(*hidden.shape[:-1], 3, 2), -np.inf, faces)
    q = faces.max(axis=-1)
    if solid == "cylinder":
        radius = (sizes[..., 0] + sizes[..., 1]) / 2
        q = np.stack([np.hypot(local[..., 0], local[..., 1]) - radius, q[..., 2]], axis=-1)
    outside = np.linalg.norm(np.maximum(q, 0.0), axis=-1)
    return np.asarray(outside + np.minimum(q.max(axis=-1), 0.0))


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
        """World points in the superquadric's frame.

        Args:
            points: Points [m], world frame, shape ``(n, 3)``.

        Returns:
            The points [m] in the superquadric's frame, shape ``(n, 3)``.
        """
        return (np.asarray(points, dtype=float) - self.position) @ self.rotation

    def inside_outside(self, points: np.ndarray) -> np.ndarray:
        """Solina-Bajcsy inside-outside function ``F`` at world points.

        Args:
            points: Points [m], world frame, shape ``(n, 3)``.

        Returns:
            ``F`` (unitless), shape ``(n,)``: below 1 inside, 1 on the surface, above 1
            outside.
        """
        e1, e2 = self.exponents
        return np.exp(_log_inside_outside(self.local(points), self.sizes, e1, e2))

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Signed first-order distance of world points to the surface (see the module
        docstring).

        Args:
            points: Points [m], world frame, shape ``(n, 3)``.

        Returns:
            Distances [m], shape ``(n,)``, positive outside.
        """
        e1, e2 = self.exponents
        return _distance(self.local(points), self.sizes, e1, e2)

    def surface(self, n: int = 24) -> np.ndarray:
        """World points on the surface (the parametric form), for figures.

        Args:
            n: Number of latitudes (``2 n`` longitudes).

        Returns:
            Points [m], world frame, shape ``(n, 2n, 3)``.
        """
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


def __getattr__(name: str) -> Any:
    """The fit's names, kept importable from here (they moved to ``fit`` and
    ``covariance``)."""
    if name in ("FitOptions", "Silhouette", "fit_superquadric"):
        from openup_ompl.perception import fit

        return getattr(fit, name)
    if name == "SuperquadricFit":
        from openup_ompl.perception.covariance import SuperquadricFit

        return SuperquadricFit
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


#: The least RMS spread [m] of a fitted cloud about its mean in its second direction:
#: 0.1 mm, a hundredth of the sensor noise's size.
MIN_SPREAD = 1e-4


def checked_points(points: np.ndarray) -> np.ndarray:
    """``points`` as an ``(N, 3)`` float array fit for the fit (see
    :func:`~openup_ompl.perception.fit.fit_superquadric`'s ``Raises``)."""
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
    spread = np.linalg.svd(points - points.mean(axis=0), compute_uv=False)
    spread = spread / math.sqrt(points.shape[0])
    if spread[1] < MIN_SPREAD:
        raise ConfigError(
            "points",
            f"{points.shape[0]} points at one place or on a line (spread {spread[1]:.2g} m)",
            f"points spread over a surface, more than {MIN_SPREAD:g} m in two directions",
        )
    return points
