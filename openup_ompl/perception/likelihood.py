"""The maximum-likelihood residual of a point measured on a scene's solid: its Mahalanobis
distance to the surface under the sensor noise's covariance at the point.

A point ``p`` is a surface point ``s`` (unknown) plus the sensor's noise, ``N(0,
Sigma_p)``: the likelihood of the solid is largest where ``sum_p min_s (p - s)^T
Sigma_p^-1 (p - s)`` is least, so each point's residual is its Mahalanobis distance to
the surface, signed (positive outside). The Euclidean distance is that residual only
when the noise is isotropic. The sensor's is not (at noise 4, about 6 mm along the
camera's axis and 4.4 across it face-on, 11 and 5 at the grazing limit): where the ray
grazes a round surface that noise runs nearly along the surface, and the Euclidean
distance reads it as shape (a 15 mm stick's fit at noise 4 shrank its radius to 13.6
mm and came 4.1 mm towards the camera, against a reported sigma of 1.3, over 20 views).

Each face of the solid is measured exactly under the metric: a plane's distance is ``n .
(p - s) / sqrt(n^T Sigma n)``; a ball's or a cylinder's round side is a quadric, whose
closest point ``s = (I + u Sigma)^-1 p`` (in the round part's own coordinates, the
cylinder's section with the marginal covariance of the noise across its axis: its
length is free along the axis) solves ``|s| = r``, one root ``u`` on ``u > -1 / d_max``
(``d`` the covariance's eigenvalues), found by Newton's method held in a bracket. The
faces' distances are joined like the Euclidean distance to a box's faces: the norm of
the positive ones outside, the largest inside (exact on every face, first order at an
edge).
"""

from __future__ import annotations

import numpy as np

__all__ = ["ROUND", "round_distance", "solid_mahalanobis"]

#: The solids the fit measures by this residual
#: (:func:`~openup_ompl.perception.fit.fit_superquadric`). A box's faces are planes, on
#: which the first-order form (the weighted Euclidean distance) is already exact; only its
#: edges differ, and there a point near a face seen at grazing incidence is nearer it in
#: the metric: solved with it from every start, the drawer's box
#: (``benchmarks/perception_stability.py --exact``) moved up to 3.5 mm at noise 3, its
#: ``u`` spread over seeds at noise 1 from 0.005 to 0.34.
ROUND = ("cylinder", "sphere")

#: Newton steps of :func:`round_distance` (from the first-order start, held in
#: its bracket).
NEWTON_STEPS = 8


def _eigh2(matrix: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``numpy.linalg.eigh`` of symmetric ``(..., 2, 2)`` matrices in closed form (no
    per-matrix call): eigenvalues ascending, eigenvectors as columns."""
    a, b, c = matrix[..., 0, 0], matrix[..., 0, 1], matrix[..., 1, 1]
    mean, half = (a + c) / 2, np.hypot((a - c) / 2, b)
    angle = np.arctan2(2 * b, a - c) / 2  # of the larger one's eigenvector
    cos, sin = np.cos(angle), np.sin(angle)
    vectors = np.stack([np.stack([-sin, cos], axis=-1), np.stack([cos, sin], axis=-1)], axis=-1)
    return np.stack([mean - half, mean + half], axis=-1), vectors


def round_distance(point: np.ndarray, radius: np.ndarray, covariance: np.ndarray) -> np.ndarray:
    """Signed Mahalanobis distance of points to a circle (``m = 2``) or a sphere (``m =
    3``) of ``radius`` about the origin.

    Args:
        point: Points, shape ``(..., m)`` [m].
        radius: Radii, broadcastable to ``(...)`` [m].
        covariance: Each point's noise covariance, shape ``(..., m, m)`` [m^2, or a
            common scale of it: the distance is then in that scale's units].

    Returns:
        ``min_s sqrt((p - s)^T Sigma^-1 (p - s))`` over the curve or surface, positive
        outside, shape ``(...)``.
    """
    values, vectors = _eigh2(covariance) if point.shape[-1] == 2 else np.linalg.eigh(covariance)
    return _round_eigen(point, radius, values, vectors)


def _round_eigen(
    point: np.ndarray, radius: np.ndarray, values: np.ndarray, vectors: np.ndarray
) -> np.ndarray:
    """:func:`round_distance` from the covariance's eigenvalues ``(..., m)`` (ascending)
    and eigenvectors ``(..., m, m)`` (columns); they broadcast against ``point``."""
    # In the eigenbasis, one array per axis (sums over a short last axis cost more than
    # the arithmetic).
    r2 = np.broadcast_to(radius, point.shape[:-1]) ** 2
    c2 = np.einsum("...ji,...j->i...", vectors, point) ** 2
    c2 = np.maximum(c2, 1e-24 * r2)  # a point at the centre: no 0 / 0
    d = np.moveaxis(values, -1, 0)
    norm2 = c2.sum(axis=0)
    outside = norm2 >= r2
    # The root of g(u) = (sum c_i^2 / (1 + u d_i)^2)^(-1/2) - 1/r, increasing on u > -1/d_max
    # (linear in u for an isotropic Sigma: Newton's first step is the root).
    low = np.where(outside, 0.0, -1.0 / d[-1])
    high = np.where(outside, (np.sqrt(norm2 / r2) - 1.0) / d[0], 0.0)
    # First-order start: u = gap / (r n^T Sigma n), n the radial direction.
    normal_variance = sum(c * v for c, v in zip(c2, d, strict=True)) / norm2
    u = (np.sqrt(norm2) - np.sqrt(r2)) / (np.sqrt(r2) * normal_variance)
    u = np.clip(u, low + (high - low) * 1e-6, high)
    for _ in range(NEWTON_STEPS):
        shrink = [c / (1.0 + u * v) ** 2 for c, v in zip(c2, d, strict=True)]
        total = sum(shrink)
        g = 1.0 / np.sqrt(total) - 1.0 / np.sqrt(r2)
        slope = sum(a * v / (1.0 + u * v) for a, v in zip(shrink, d, strict=True)) / total**1.5
        low = np.where(g < 0, u, low)
        high = np.where(g < 0, high, u)
        step = u - g / np.maximum(slope, 1e-300)
        u = np.where((step >= low) & (step <= high), step, (low + high) / 2)
    distance2 = sum(c * v * (u / (1.0 + u * v)) ** 2 for c, v in zip(c2, d, strict=True))
    return np.asarray(np.sign(u) * np.sqrt(distance2))


def solid_mahalanobis(
    local: np.ndarray,
    sizes: np.ndarray,
    solid: str,
    covariances: np.ndarray,
    hidden: np.ndarray | None = None,
) -> np.ndarray:
    """Signed Mahalanobis distance of points to a box, a cylinder about z (radius the
    mean of ``a1, a2``) or a ball (radius the mean of the three), in the solid's frame
    (module docstring). The ``hidden`` faces (``(..., 6)``, ``+x, -x, +y, -y, +z, -z``;
    a cylinder's ends are its ``z`` faces) are left out, as in
    :func:`~openup_ompl.perception.superquadric._solid_distance`.

    Args:
        local: Points in the solid's frame, shape ``(..., 3)`` [m].
        sizes: Half-sizes, broadcastable to ``local`` [m].
        solid: ``"box"``, ``"cylinder"`` or ``"sphere"``.
        covariances: Each point's noise covariance in the solid's frame, shape ``(...,
            3, 3)`` [m^2, or a common scale of it].
        hidden: Faces left out, or None.

    Returns:
        The distances, shape ``(...)``, positive outside (in the covariance's units:
        ``Sigma`` divided by ``sigma^2`` gives metres at a noise of ``sigma``).
    """
    if solid == "sphere":
        return round_distance(local, sizes.mean(axis=-1), covariances)
    spread = np.sqrt(np.diagonal(covariances, axis1=-2, axis2=-1))  # along each axis
    plus, minus = (local - sizes) / spread, (-local - sizes) / spread
    if hidden is not None:
        plus = np.where(hidden[..., 0::2], -np.inf, plus)
        minus = np.where(hidden[..., 1::2], -np.inf, minus)
    q = np.maximum(plus, minus)
    parts = [q[..., 0], q[..., 1], q[..., 2]]
    if solid == "cylinder":
        radius = (sizes[..., 0] + sizes[..., 1]) / 2
        parts = [round_distance(local[..., :2], radius, covariances[..., :2, :2]), q[..., 2]]
    outside = np.sqrt(sum(np.maximum(part, 0.0) ** 2 for part in parts))
    largest = parts[0]
    for part in parts[1:]:
        largest = np.maximum(largest, part)
    return np.asarray(outside + np.minimum(largest, 0.0))
