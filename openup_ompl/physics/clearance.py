"""Geometry of the shared approach (:mod:`~openup_ompl.physics.approach`): where the object
rests (:func:`support`), how far a body or a geom moves over a stretch of states
(:func:`travel`), and whether two sets of geoms are clear of
each other (:func:`spheres_apart`, :func:`exactly_apart`).

Clearance is judged as MuJoCo judges contact: two geoms can touch only if their distance
falls below their margins; bounding spheres (``geom_rbound``) first, MuJoCo's own
distance (``mj_geomDistance``) where the spheres meet.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    "Move", "Support", "body_radius", "exactly_apart", "footprint", "spheres_apart", "support",
    "travel",
]  # fmt: skip


@dataclass
class Support:
    """The object's support: the top face of one fixed box (or a horizontal plane).

    Attributes:
        box: The supporting box ``(centre, rotation, half-sizes)``; ``None`` for a plane.
        geom: The supporting geom's index.
        start: The object's start position [m] (its body origin).
    """

    box: tuple[np.ndarray, np.ndarray, np.ndarray] | None
    geom: int
    start: np.ndarray

    def holds(self, shift: np.ndarray, radius: float) -> bool:
        """Whether the object, moved by ``shift`` [m], stands on the same face, a circle
        of ``radius`` [m] about it (:func:`footprint`) within the face's outline."""
        if self.box is None:
            return True
        position, rotation, half = self.box
        local = rotation.T @ (self.start + shift - position)
        return bool(np.all(np.abs(local[:2]) + radius <= half[:2]))


@dataclass(frozen=True)
class Move:
    """The rigid move from the nominal object's start to a trial's: a turn about the
    vertical through the nominal start, then a shift (:meth:`between`).

    Attributes:
        origin: The nominal start position [m].
        shift: The trial's start position minus it [m].
        turn: The turn's rotation matrix (about the world z axis), or ``None``: no turn.
        quat: The turn as a scalar-first unit quaternion.
    """

    origin: np.ndarray
    shift: np.ndarray
    turn: np.ndarray | None
    quat: np.ndarray

    @staticmethod
    def between(nominal: np.ndarray, start: np.ndarray) -> Move | None:
        """The move from ``nominal`` to ``start`` (free-joint ``qpos``: position, then
        scalar-first quaternion), or ``None``: another height, or a turn about anything
        but the vertical."""
        import mujoco

        if start[2] != nominal[2]:
            return None
        shift = start[:3] - nominal[:3]
        if np.array_equal(start[3:], nominal[3:]):
            return Move(nominal[:3].copy(), shift, None, np.array([1.0, 0.0, 0.0, 0.0]))
        inverse, quat = np.empty(4), np.empty(4)
        mujoco.mju_negQuat(inverse, nominal[3:])
        mujoco.mju_mulQuat(quat, start[3:], inverse)
        quat /= np.linalg.norm(quat)
        if abs(quat[1]) > 1e-12 or abs(quat[2]) > 1e-12:
            return None
        turn = np.empty(9)
        mujoco.mju_quat2Mat(turn, quat)
        return Move(nominal[:3].copy(), shift, turn.reshape(3, 3), quat)

    def points(self, points: np.ndarray) -> np.ndarray:
        """``points`` [m] (last axis xyz) moved."""
        if self.turn is None:
            return points + self.shift
        return (points - self.origin) @ self.turn.T + self.origin + self.shift

    def vectors(self, vectors: np.ndarray) -> np.ndarray:
        """World-frame ``vectors`` (last axis xyz) turned."""
        return vectors if self.turn is None else vectors @ self.turn.T

    def quats(self, quats: np.ndarray) -> np.ndarray:
        """Scalar-first orientations ``(n, 4)`` turned."""
        if self.turn is None:
            return quats
        w, x, y, z = self.quat
        a, b, c, d = quats.T
        return np.stack([w * a - z * d, w * b - z * c, w * c + z * b, w * d + z * a], axis=1)


def support(model: Any, state: np.ndarray) -> Support | None:
    """The object's support at ``state`` (a full physics state of the world), or
    ``None``: it touches two things, nothing, anything but a fixed obstacle, or something
    other than a box's horizontal face or a horizontal plane. (The other fixed obstacles'
    clearance is the caller's: :func:`exactly_apart`.)

    Args:
        model: The world's ``mujoco.MjModel`` (its object body named ``object``).
        state: Its full physics state.

    Returns:
        The support, or ``None``.
    """
    import mujoco

    data = mujoco.MjData(model)
    mujoco.mj_setState(model, data, state, int(mujoco.mjtState.mjSTATE_FULLPHYSICS))
    mujoco.mj_forward(model, data)
    body = model.body("object").id
    touched = set()
    for contact in data.contact[: data.ncon]:
        a, b = (int(g) for g in contact.geom)
        if body in (model.geom_bodyid[a], model.geom_bodyid[b]):
            touched.add(b if model.geom_bodyid[a] == body else a)
    if len(touched) != 1:
        return None
    (under,) = touched
    rotation = data.geom_xmat[under].reshape(3, 3).copy()
    if model.geom_bodyid[under] != 0 or abs(rotation[2, 2]) != 1.0:
        return None  # not fixed, or its local z not the world's vertical
    kind = int(model.geom_type[under])
    box = None
    if kind == mujoco.mjtGeom.mjGEOM_BOX:
        box = (data.geom_xpos[under].copy(), rotation, model.geom_size[under].copy())
    elif kind != mujoco.mjtGeom.mjGEOM_PLANE:
        return None
    return Support(box, under, data.xpos[body].copy())


def body_radius(model: Any, body: int) -> float:
    """Radius [m] of a sphere about ``body``'s origin enclosing its geoms and margins."""
    geoms = np.flatnonzero(model.geom_bodyid == body)
    return float(
        max(np.linalg.norm(model.geom_pos[g]) + model.geom_rbound[g] + model.geom_margin[g]
            for g in geoms)
    )  # fmt: skip


def footprint(model: Any, data: Any, body: int) -> float:
    """Radius [m] of a vertical cylinder about ``body``'s origin enclosing its geoms'
    bounding boxes (MuJoCo's ``geom_aabb``) at ``data``'s kinematics: how far the body
    reaches sideways."""
    reach = 0.0
    for g in np.flatnonzero(model.geom_bodyid == body):
        centre, half = model.geom_aabb[g][:3], model.geom_aabb[g][3:]
        signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
        corners = (centre + signs * half) @ data.geom_xmat[g].reshape(3, 3).T
        corners += data.geom_xpos[g] - data.xpos[body]
        reach = max(reach, float(np.linalg.norm(corners[:, :2], axis=1).max()))
    return reach + float(model.geom_margin[model.geom_bodyid == body].max())


def travel(centres: np.ndarray, axes: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """How far [m] any point within ``radius`` of each frame's origin is, at each state,
    from where it was at the first: the origin's shift plus the rotation's change times
    the radius.

    Args:
        centres: ``(states, n, 3)`` the frames' origins [m] (geoms' centres, bodies').
        axes: ``(states, n, 9)`` their rotation matrices.
        radius: ``(n,)`` the radii [m].

    Returns:
        ``(states, n)`` the bound [m].
    """
    shift = np.linalg.norm(centres - centres[0], axis=2)
    turn = np.linalg.norm(axes - axes[0], axis=2)  # Frobenius >= spectral
    return np.asarray(shift + turn * radius)


def spheres_apart(a: np.ndarray, ra: np.ndarray, b: np.ndarray, rb: np.ndarray) -> np.ndarray:
    """Per state, whether every sphere of ``a`` is apart from every sphere of ``b``.

    Args:
        a: ``(states, n, 3)`` centres [m]; ``ra`` ``(n,)`` radii [m].
        b: ``(states, m, 3)`` centres [m]; ``rb`` ``(m,)`` radii [m].

    Returns:
        ``(states,)`` flags.
    """
    if not a.shape[1] or not b.shape[1]:
        return np.ones(len(a), dtype=bool)
    gaps = np.linalg.norm(a[:, :, None] - b[:, None], axis=3) - ra[:, None] - rb
    return (gaps > 0).all(axis=(1, 2))


def exactly_apart(
    model: Any, data: Any, pairs: list[tuple[int, int]], travel: dict[int, float]
) -> bool:
    """Whether each geom pair stays apart while each geom moves up to ``travel[g]`` [m]:
    MuJoCo's distance at ``data``'s kinematics beyond the two travels and margins.

    Args:
        model: The model.
        data: Its data, kinematics computed.
        pairs: Geom index pairs.
        travel: Per geom of ``pairs``, how far it may move [m].

    Returns:
        True if no pair can come within its margins.
    """
    import mujoco

    for g, h in pairs:
        need = travel[g] + travel[h] + model.geom_margin[g] + model.geom_margin[h] + 1e-9
        gap = np.linalg.norm(data.geom_xpos[g] - data.geom_xpos[h])
        bounded = model.geom_rbound[g] > 0 and model.geom_rbound[h] > 0  # a plane's is 0
        if bounded and gap - model.geom_rbound[g] - model.geom_rbound[h] > need:
            continue
        if mujoco.mj_geomDistance(model, data, g, h, need + 0.01, None) <= need:
            return False
    return True
