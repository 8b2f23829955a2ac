"""The paper's hand law: Algorithm 3 (``OpenHand``) and Algorithm 1 (``GetGoalDist``).

The open finger configuration is a linear function of the normalised palm-to-grasp
distance ``d`` and of the pose uncertainty ``u``, between the referential hand
configurations ``c`` (close preshape, reached at the grasp), ``b`` (base open hand) and
``w`` (widest opening), with the maximum grip aperture at ``d = mga``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from openup_ompl.exceptions import ConfigError

#: Names accepted for :attr:`HandLaw.distance`.
DISTANCE_KINDS = ("translation", "weighted")


def _check_unit(name: str, value: float, *, low_open: bool = False) -> float:
    value = float(value)
    ok = math.isfinite(value) and (value > 0.0 if low_open else value >= 0.0) and value <= 1.0
    if not ok:
        raise ConfigError(name, value, "a number in (0, 1]" if low_open else "a number in [0, 1]")
    return value


def open_hand(
    d: float,
    c: Sequence[float] | np.ndarray,
    b: Sequence[float] | np.ndarray,
    w: Sequence[float] | np.ndarray,
    u: float,
    mga: float,
    *,
    continuous: bool = False,
    open_arrival: bool = False,
) -> np.ndarray:
    """Open finger configuration for a normalised distance ``d`` (the paper's Algorithm 3).

    For ``d <= mga``: ``c + (d / mga) * ((b - c) + (w - c) * u)``; otherwise
    ``b + (w - b) * u``.

    As printed in the paper the law is discontinuous at ``d = mga`` whenever ``u > 0``
    and ``b != c``: just below ``mga`` it gives ``b + (w - c) u``, just above
    ``b + (w - b) u``, a jump of ``(b - c) u``. ``continuous=True`` uses
    ``c + (d / mga) * ((b - c) + (w - b) * u)`` below ``mga`` instead, which meets the
    plateau ``b + (w - b) u`` exactly at ``d = mga``.

    ``open_arrival=True`` is an extension: Algorithm 3 returns ``c`` at the grasp for
    every ``u``, so the hand that meets a displaced object is the same whatever the
    uncertainty; the paper's text ("the open finger configuration to grasp the object
    varies linearly between c and w") suggests an opening at the grasp that grows with
    ``u``. This variant arrives at ``c_u = c + (w - c) u`` and keeps the plateau
    ``b_u = b + (w - b) u``: ``c_u + (d / mga) (b_u - c_u)`` below ``mga`` (continuous
    at ``mga``; ``continuous`` then changes nothing). At ``u = 0`` both are the paper's.

    Args:
        d: Normalised palm-to-grasp distance (Algorithm 1), ``>= 0``; 0 at the grasp,
            1 at the start, larger when the palm is farther than at the start.
        c: Close preshape [hand joint units, rad or m], reached at ``d = 0``.
        b: Base open configuration.
        w: Widest open configuration.
        u: Pose uncertainty in [0, 1].
        mga: Normalised distance of maximum grip aperture, in (0, 1].
        continuous: Use the variant without the jump at ``mga``.
        open_arrival: Use the variant that arrives at the grasp opened by ``u``.

    Returns:
        The hand configuration, in the order of ``c``. Not clipped to joint limits
        (:class:`HandLaw` clips).

    Raises:
        ConfigError: ``u`` or ``mga`` out of range, ``d`` negative or not finite, or
            ``c``, ``b``, ``w`` of different lengths.
    """
    u = _check_unit("u", u)
    mga = _check_unit("mga", mga, low_open=True)
    d = float(d)
    if not (math.isfinite(d) and d >= 0.0):
        raise ConfigError("d", d, "a finite normalised distance >= 0")
    c_, b_, w_ = (np.asarray(x, dtype=float) for x in (c, b, w))
    if not (c_.shape == b_.shape == w_.shape and c_.ndim == 1):
        raise ConfigError("c, b, w", (c_.shape, b_.shape, w_.shape), "three vectors of one length")
    plateau = b_ + (w_ - b_) * u
    if d > mga:
        return plateau
    if open_arrival:
        arrival = c_ + (w_ - c_) * u
        return arrival + (d / mga) * (plateau - arrival)
    far = w_ - b_ if continuous else w_ - c_
    return c_ + (d / mga) * ((b_ - c_) + far * u)


@dataclass(frozen=True)
class HandLaw:
    """The hand law of one problem: referential configurations, ``u``, ``mga`` and limits.

    The law is precomputed into an affine form so that the validity checker's hot path
    costs one multiply-add: ``hand = arrival + d * low_slope`` for ``d <= mga`` and
    ``high`` above, then clipped to ``[lower, upper]``.

    Attributes:
        c: Close preshape, hand-joint order.
        b: Base open configuration.
        w: Widest open configuration.
        u: Pose uncertainty in [0, 1].
        mga: Normalised distance of maximum grip aperture, in (0, 1].
        lower: Hand joint lower limits.
        upper: Hand joint upper limits.
        continuous: Use the variant without the jump at ``mga``.
        open_arrival: Use the variant that reaches the grasp opened by ``u``, at
            ``c + (w - c) u`` (see :func:`open_hand`).
        distance: ``"translation"``: Euclidean distance [m] between the palm origin and the
            grasp position (the default). ``"weighted"``: that plus ``rotation_weight``
            [m/rad] times the palm-to-grasp rotation angle.
        rotation_weight: [m/rad], used when ``distance == "weighted"``.
        fixed: If set, the classical fixed preshape: the hand stays at this configuration
            for the whole reach, whatever ``d`` (the baseline the paper improves on).
    """

    c: np.ndarray
    b: np.ndarray
    w: np.ndarray
    u: float
    mga: float
    lower: np.ndarray
    upper: np.ndarray
    continuous: bool = False
    open_arrival: bool = False
    distance: str = "translation"
    rotation_weight: float = 0.1  # [m/rad]
    fixed: np.ndarray | None = None
    arrival: np.ndarray = field(init=False, repr=False, compare=False)
    low_slope: np.ndarray = field(init=False, repr=False, compare=False)
    high: np.ndarray = field(init=False, repr=False, compare=False)
    clip_low: bool = field(init=False, repr=False, compare=False)
    fixed_clipped: np.ndarray | None = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        arrays = {}
        for name in ("c", "b", "w", "lower", "upper"):
            value = np.array(getattr(self, name), dtype=float)
            if value.ndim != 1 or not np.all(np.isfinite(value)):
                raise ConfigError(f"hand.{name}", getattr(self, name), "a finite list of numbers")
            arrays[name] = value
        n = arrays["lower"].size
        for name in ("c", "b", "w"):
            if arrays[name].size != n:
                raise ConfigError(
                    f"hand.{name}", arrays[name].tolist(), f"{n} values, one per hand joint"
                )
        if self.fixed is not None:
            fixed = np.array(self.fixed, dtype=float)
            if fixed.shape != (n,) or not np.all(np.isfinite(fixed)):
                raise ConfigError("fixed hand", self.fixed, f"{n} finite values")
            object.__setattr__(self, "fixed", fixed)
        if self.distance not in DISTANCE_KINDS:
            raise ConfigError("hand law distance", self.distance, f"one of {DISTANCE_KINDS}")
        if not (math.isfinite(self.rotation_weight) and self.rotation_weight >= 0):
            raise ConfigError("rotation_weight", self.rotation_weight, "a number >= 0 [m/rad]")
        for name, value in arrays.items():
            value.flags.writeable = False
            object.__setattr__(self, name, value)
        object.__setattr__(self, "u", _check_unit("u", self.u))
        object.__setattr__(self, "mga", _check_unit("mga", self.mga, low_open=True))
        c, b, w = arrays["c"], arrays["b"], arrays["w"]
        lower, upper = arrays["lower"], arrays["upper"]
        plateau = b + (w - b) * self.u
        if self.open_arrival:
            arrival = c + (w - c) * self.u
            slope = (plateau - arrival) / self.mga
        else:
            arrival = c.copy()
            far = w - b if self.continuous else w - c
            slope = ((b - c) + far * self.u) / self.mga
        # The low branch is affine in d: it stays within the limits for every d in
        # [0, mga] when both of its ends do, and then needs no clipping at run time.
        ends = np.stack([arrival, arrival + self.mga * slope])
        clip_low = bool(np.any(ends < lower) or np.any(ends > upper))
        fixed_clipped = None if self.fixed is None else np.clip(self.fixed, lower, upper)
        derived: tuple[tuple[str, np.ndarray | None], ...] = (
            ("arrival", arrival),
            ("low_slope", slope),
            ("high", np.clip(plateau, lower, upper)),
            ("fixed_clipped", fixed_clipped),
        )
        for name, item in derived:
            if item is not None:
                item.flags.writeable = False
            object.__setattr__(self, name, item)
        object.__setattr__(self, "clip_low", clip_low)

    @property
    def size(self) -> int:
        """Number of hand joints."""
        return int(self.c.size)

    def __call__(self, d: float) -> np.ndarray:
        """Hand configuration at normalised distance ``d``, clipped to the joint limits."""
        if self.fixed_clipped is not None:
            return self.fixed_clipped.copy()
        if d > self.mga:
            return self.high.copy()
        return np.clip(self.arrival + d * self.low_slope, self.lower, self.upper)

    def batch(self, d: np.ndarray) -> np.ndarray:
        """Hand configurations for a vector of distances: shape ``(len(d), size)``."""
        d = np.asarray(d, dtype=float)[:, None]
        if self.fixed_clipped is not None:
            return np.repeat(self.fixed_clipped[None, :], d.shape[0], axis=0)
        low = np.clip(self.arrival + d * self.low_slope, self.lower, self.upper)
        return np.where(d > self.mga, self.high, low)

    def with_options(self, **changes: object) -> HandLaw:
        """A copy with some fields replaced (e.g. ``u``), validated again."""
        fields = {
            name: getattr(self, name)
            for name in (
                "c",
                "b",
                "w",
                "u",
                "mga",
                "lower",
                "upper",
                "continuous",
                "open_arrival",
                "distance",
                "rotation_weight",
                "fixed",
            )
        }
        fields.update(changes)
        return HandLaw(**fields)  # type: ignore[arg-type]

    def to_dict(self) -> dict[str, object]:
        """The law as written in a plan file (CONTRACT §4, ``hand_law``)."""
        return {
            "c": self.c.tolist(),
            "b": self.b.tolist(),
            "w": self.w.tolist(),
            "u": self.u,
            "mga": self.mga,
            "continuous": self.continuous,
            "open_arrival": self.open_arrival,
            "distance": self.distance,
            "rotation_weight": self.rotation_weight,
            "fixed": None if self.fixed is None else self.fixed.tolist(),
        }


class GoalDistance:
    """Algorithm 1: palm-to-grasp distance normalised by its value at the start.

    ``d(q) = D(FK(q), T_goal) / D(FK(q_start), T_goal)``, with ``D`` the Euclidean distance
    between the palm frame origin and the grasp position [m] (``"translation"``), or that
    plus ``rotation_weight`` [m/rad] times the rotation angle between them (``"weighted"``).

    Args:
        grasp: Grasp pose of the palm frame in the world frame.
        start_placement: Palm frame placement at the start configuration (world frame).
        distance: ``"translation"`` or ``"weighted"``.
        rotation_weight: [m/rad] for the weighted distance.
    """

    def __init__(
        self,
        grasp: pin.SE3,
        start_placement: pin.SE3,
        distance: str = "translation",
        rotation_weight: float = 0.1,
    ) -> None:
        if distance not in DISTANCE_KINDS:
            raise ConfigError("hand law distance", distance, f"one of {DISTANCE_KINDS}")
        self._goal = grasp.translation.copy()
        self._goal_rot_t = grasp.rotation.T.copy()
        self._weighted = distance == "weighted"
        self._rotation_weight = float(rotation_weight)
        self.start_distance = self.raw(start_placement)
        if self.start_distance <= 1e-9:
            raise ConfigError(
                "start", self.start_distance, "a start whose palm is away from the grasp pose"
            )
        self._inv_start = 1.0 / self.start_distance

    def raw(self, placement: pin.SE3) -> float:
        """Un-normalised distance ``D`` [m] of a palm placement to the grasp."""
        p = placement.translation
        dx, dy, dz = p[0] - self._goal[0], p[1] - self._goal[1], p[2] - self._goal[2]
        dist = math.sqrt(dx * dx + dy * dy + dz * dz)
        if self._weighted:
            angle = np.linalg.norm(pin.log3(self._goal_rot_t @ placement.rotation))
            dist += self._rotation_weight * float(angle)
        return dist

    def __call__(self, placement: pin.SE3) -> float:
        """Normalised distance ``d`` of a palm placement (0 at the grasp, 1 at the start)."""
        return self.raw(placement) * self._inv_start
