"""Grasp quality: is a set of contacts a grasp? Pure numpy and SciPy, no robot or scene.

:func:`force_closure`: point (or soft-finger) contacts with Coulomb friction, each cone
linearised by ``edges`` generators; the object is in force closure when the contact
wrenches positively span R^6, decided exactly by a linear program (HiGHS through SciPy):
rank 6 and a strictly positive combination summing to zero. :func:`enclosed` is the
simpler answer: without friction, the contact normals alone hold the object in the plane
across its axis.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from openup_ompl._toml import floats, is_finite, is_integer, shown
from openup_ompl.exceptions import ConfigError

__all__ = [
    "DEFAULT_FRICTION",
    "MAX_TORSION",
    "check_torsion",
    "contact_wrenches",
    "enclosed",
    "force_closure",
    "positively_spans",
]

#: Coulomb friction coefficient of the grasp test (rubber-coated fingertips on a can).
DEFAULT_FRICTION = 0.5
#: Largest soft-finger torsional friction lever [m] accepted, far beyond any finger pad.
MAX_TORSION = 0.1
#: The most generators per linearised friction cone (8 is the default; 64 is within
#: 0.2 % of the cone: its inscribed radius is cos(pi / 64) = 0.9988 of it).
MAX_EDGES = 64


def _rows(value: object, where: str) -> np.ndarray:
    """``value`` as ``(K, 3)`` floats, else :class:`ConfigError` naming ``where``."""
    array = floats(value)
    if array is None:
        raise ConfigError(where, value, "rows of [x, y, z]")
    if array.size % 3:
        raise ConfigError(where, array.shape, "rows of [x, y, z]")
    return array.reshape(-1, 3)


def _as_contacts(points: object, normals: object, where: str) -> tuple[np.ndarray, np.ndarray]:
    p = _rows(points, f"{where}: points")
    n = _rows(normals, f"{where}: normals")
    if p.shape != n.shape:
        raise ConfigError(f"{where}: normals", n.shape, f"one normal per point {p.shape}")
    if not (np.isfinite(p).all() and np.isfinite(n).all()):
        raise ConfigError(f"{where}: contacts", "non-finite values", "finite points and normals")
    length = np.linalg.norm(n, axis=1)
    if np.any(length < 1e-9):
        raise ConfigError(f"{where}: normals", n[length < 1e-9][0].tolist(), "non-zero normals")
    return p, n / length[:, None]


def _tangents(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing each unit row of ``n`` ``(K, 3)`` to a right-handed
    orthonormal basis."""
    helper = np.where(np.abs(n[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    t1 = np.cross(n, helper)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    return t1, np.cross(n, t1)


def check_torsion(torsion: float) -> float:
    """``torsion`` if it is a soft-finger torsional friction lever in [0, MAX_TORSION] m.

    Args:
        torsion: The lever [m].

    Returns:
        ``torsion`` as a float [m].

    Raises:
        ConfigError: Otherwise.
    """
    if not (is_finite(torsion) and 0 <= torsion <= MAX_TORSION):
        raise ConfigError(
            "torsion", torsion, f"a torsional friction lever in [0, {MAX_TORSION:g}] m"
        )
    return float(torsion)


def positively_spans(vectors: np.ndarray) -> bool:
    """Whether the columns of ``vectors`` ``(m, K)`` positively span R^m.

    Exactly when they have rank ``m`` and some combination with every coefficient at
    least 1 sums to zero (then any vector is a positive combination, and conversely);
    the second part is a linear-programming feasibility problem.

    Args:
        vectors: The vectors as columns, ``(m, K)``.

    Returns:
        True if every vector of R^m is a non-negative combination of the columns.
    """
    from scipy.optimize import linprog

    vectors = np.asarray(vectors, dtype=float)
    m, k = vectors.shape
    if k <= m:
        return False
    singular = np.linalg.svd(vectors, compute_uv=False)
    if singular[-1] <= 1e-9 * singular[0]:
        return False
    result = linprog(
        np.zeros(k), A_eq=vectors, b_eq=np.zeros(m), bounds=[(1.0, None)] * k, method="highs"
    )
    return bool(result.status == 0)


def contact_wrenches(
    points: object,
    normals: object,
    *,
    friction: float = DEFAULT_FRICTION,
    edges: int = 8,
    center: Sequence[float] | None = None,
    torsion: float = 0.0,
) -> np.ndarray:
    """The primitive wrenches ``(6, K * edges)`` of point contacts with friction
    (``(6, K * (edges + 2))`` with ``torsion``).

    Each contact's friction cone (half-angle ``atan(friction)`` about the inward
    ``normal``) is linearised by ``edges`` unit-normal-force generators; a generator
    ``f`` at ``p`` has wrench ``[f, (p - center) x f / scale]``, with torques divided by
    the contacts' mean distance to ``center`` [m] (default: their centroid) so that both
    halves have comparable size. The scale changes no decision.

    With ``torsion`` > 0 [m] the contacts are soft fingers: each also resists a torque
    about its normal of up to ``torsion`` times its normal force (a pad's torsional
    friction, about ``2/3 friction`` times the contact patch radius), linearised by two
    more generators ``[n, (p - center) x n / scale +- torsion n / scale]``: an inner
    approximation of the soft-finger limit, so a grasp found in force closure is one.

    Args:
        points: Contact points ``(K, 3)`` [m], world frame.
        normals: Inward contact normals ``(K, 3)``.
        friction: Coulomb coefficient.
        edges: Generators of each linearised cone.
        center: Torque reference [m] (default: the contacts' centroid).
        torsion: Soft-finger torsional friction [m] (0: point contacts).

    Returns:
        The wrenches as columns ``(6, K * edges)``, or ``(6, K * (edges + 2))`` with
        ``torsion``; forces in units of the normal force, torques divided by the mean
        contact distance (so dimensionless).
    """
    p, n = _as_contacts(points, normals, "contact_wrenches")
    if not (is_finite(friction) and friction >= 0):
        raise ConfigError("friction", friction, "a coefficient >= 0")
    if not (is_integer(edges) and 3 <= edges <= MAX_EDGES):
        raise ConfigError("edges", edges, f"an integer in [3, {MAX_EDGES}] per friction cone")
    origin = p.mean(axis=0) if center is None else floats(center)
    if origin is None or origin.shape != (3,) or not np.isfinite(origin).all():
        raise ConfigError("center", shown(center), "a point [x, y, z] of finite numbers [m]")
    arms = p - origin
    scale = max(float(np.linalg.norm(arms, axis=1).mean()), 1e-9)
    t1, t2 = _tangents(n)
    angles = 2 * np.pi * np.arange(edges) / edges
    forces = (
        n[:, None, :]
        + friction * np.cos(angles)[None, :, None] * t1[:, None, :]
        + friction * np.sin(angles)[None, :, None] * t2[:, None, :]
    ).reshape(-1, 3)
    torques = np.cross(np.repeat(arms, edges, axis=0), forces) / scale
    if check_torsion(torsion) > 0:
        centre = np.cross(arms, n) / scale
        twist = torsion * n / scale
        forces = np.concatenate([forces, n, n])
        torques = np.concatenate([torques, centre + twist, centre - twist])
    return np.concatenate([forces, torques], axis=1).T


def force_closure(
    points: object,
    normals: object,
    *,
    friction: float = DEFAULT_FRICTION,
    edges: int = 8,
    center: Sequence[float] | None = None,
    torsion: float = 0.0,
) -> bool:
    """Whether point contacts with friction hold the object in force closure: their
    wrenches (:func:`contact_wrenches`) positively span R^6, so the fingers can resist
    any external force and torque on the object.

    Args:
        points: Contact points ``(K, 3)`` [m], world frame.
        normals: Inward contact normals ``(K, 3)`` (the direction each finger pushes).
        friction: Coulomb coefficient (default :data:`DEFAULT_FRICTION`).
        edges: Generators of each linearised cone (8: an inscribed octagon).
        center: Torque reference [m] (the decision does not depend on it).
        torsion: Soft-finger torsional friction [m] (0: point contacts, under which two
            contacts are never in force closure: nothing resists a rotation about the
            line through them).

    Returns:
        True if the contacts' wrenches positively span R^6.
    """
    wrenches = contact_wrenches(
        points, normals, friction=friction, edges=edges, center=center, torsion=torsion
    )
    return positively_spans(wrenches)


def enclosed(normals: object, axis: Sequence[float] | np.ndarray | None = None) -> bool:
    """Whether the fingers enclose the object: the inward contact normals, projected
    on the plane across ``axis``, positively span that plane, so that the object cannot
    slide out sideways even without friction.

    Args:
        normals: Inward contact normals ``(K, 3)``.
        axis: The object's long axis (:func:`object_axis`); ``None`` (a sphere) uses the
            normal of the plane the contact normals lie closest to.

    Returns:
        True if the projected normals positively span the plane (fewer than 3
        contacts never do).
    """
    n = _rows(normals, "enclosed: normals")
    if not np.isfinite(n).all():
        raise ConfigError("enclosed: normals", "non-finite values", "finite normals")
    if n.shape[0] < 3:
        return False
    if axis is None:
        axis = np.linalg.svd(n)[2][-1]
    given = floats(axis)
    length = float(np.linalg.norm(given)) if given is not None and given.shape == (3,) else 0.0
    if given is None or not (math.isfinite(length) and length > 1e-9):
        raise ConfigError("enclosed: axis", shown(axis), "a finite non-zero 3-vector")
    a = given / length
    e1, e2 = _tangents(a[None, :])
    planar = np.stack([n @ e1[0], n @ e2[0]])
    keep = np.linalg.norm(planar, axis=0) > 1e-6
    return positively_spans(planar[:, keep])
