"""The paper's hand law: Algorithm 3 (``OpenHand``) and Algorithm 1 (``GetGoalDist``).

The open finger configuration is a linear function of the normalised palm-to-grasp
distance ``d`` and of the pose uncertainty ``u``, between the referential hand
configurations ``c`` (close preshape, reached at the grasp), ``b`` (base open hand) and
``w`` (widest opening), with the maximum grip aperture at ``d = mga``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin

from openup_ompl._toml import floats, is_finite, is_number, shown, unknown_key
from openup_ompl.exceptions import ConfigError

#: Names accepted for :attr:`HandLaw.distance`.
DISTANCE_KINDS = ("translation", "weighted")
#: Weight of the palm-to-grasp rotation angle in a task-space distance [m/rad]: the
#: ``"weighted"`` law distance's default and the goal region's error (0.1 m per rad: 1 mm
#: of position counts as much as 0.01 rad).
ROTATION_WEIGHT = 0.1


def palm_distance(
    placement: pin.SE3,
    goal_position: np.ndarray,
    goal_rotation_t: np.ndarray | None = None,
    rotation_weight: float = ROTATION_WEIGHT,
) -> float:
    """Task-space distance [m] of a palm placement to a grasp (world frame): the Euclidean
    distance between their origins plus ``rotation_weight`` [m/rad] times the angle of the
    rotation between them (left out when ``goal_rotation_t`` is ``None``).

    Args:
        placement: The palm frame's placement.
        goal_position: The grasp position [m].
        goal_rotation_t: The transpose of the grasp rotation, or ``None`` for the
            translation alone.
        rotation_weight: [m/rad].

    Returns:
        The distance [m].
    """
    p = placement.translation
    dx, dy, dz = p[0] - goal_position[0], p[1] - goal_position[1], p[2] - goal_position[2]
    dist = math.sqrt(dx * dx + dy * dy + dz * dz)
    if goal_rotation_t is not None:
        angle = np.linalg.norm(pin.log3(goal_rotation_t @ placement.rotation))
        dist += rotation_weight * float(angle)
    return dist


#: How far [rad or m] a referential hand configuration may lie beyond a joint limit
#: (rounding in a robot or scene file); it is then clipped to the limit.
REFERENCE_TOLERANCE = 1e-6
#: The smallest ``mga`` accepted. Below it the hand would snap open within 1 % of the reach:
#: the fingers' speed bound grows as ``1 / mga``, and with it the states a motion check
#: places near the grasp, until one check outlasts a planning time limit.
MGA_MIN = 0.01


def _check_unit(name: str, value: float, *, low: float = 0.0, low_open: bool = False) -> float:
    """``value`` as a float if it is a number in ``[low, 1]`` (``(low, 1]`` if
    ``low_open``), else :class:`ConfigError`."""
    expected = f"a number in {'(' if low_open else '['}{low:g}, 1]"
    if not is_number(value):
        raise ConfigError(name, value, expected)
    value = float(value)
    above = low < value if low_open else low <= value
    if not (math.isfinite(value) and above and value <= 1.0):
        raise ConfigError(name, value, expected)
    return value


def _check_distance(d: float) -> float:
    """``d`` as a float if it is a finite normalised distance ``>= 0``."""
    if not (is_finite(d) and d >= 0.0):
        raise ConfigError("d", d, "a finite normalised distance >= 0")
    d = float(d)
    return d


def _check_weight(name: str, value: float) -> float:
    """``value`` as a float if it is a rotation weight, a finite number ``>= 0`` [m/rad]."""
    if not (is_finite(value) and value >= 0):
        raise ConfigError(name, value, "a number >= 0 [m/rad]")
    return float(value)


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
        mga: Normalised distance of maximum grip aperture, in (0, 1] (a
            :class:`HandLaw`, which plans, needs at least :data:`MGA_MIN`).
        continuous: Use the variant without the jump at ``mga``.
        open_arrival: Use the variant that arrives at the grasp opened by ``u``.

    Returns:
        The hand configuration, in the order of ``c``. Not clipped to joint limits
        (:class:`HandLaw` clips).

    Raises:
        ConfigError: ``u`` or ``mga`` out of range or not a number, ``d`` negative or
            not finite, ``c``, ``b``, ``w`` not finite or of different lengths.
    """
    u = _check_unit("u", u)
    for name, flag in (("continuous", continuous), ("open_arrival", open_arrival)):
        if not isinstance(flag, (bool, np.bool_)):  # the string "no" would count as true
            raise ConfigError(name, flag, "true or false")
    # Any mga in (0, 1] is a law; planning needs mga >= MGA_MIN (HandLaw checks that).
    mga = _check_unit("mga", mga, low_open=True)
    d = _check_distance(d)
    refs = []
    for name, value in (("c", c), ("b", b), ("w", w)):
        try:
            ref = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            ref = np.full(1, np.nan)
        if not np.all(np.isfinite(ref)):
            raise ConfigError(name, value, "a finite list of numbers")
        refs.append(ref)
    c_, b_, w_ = refs
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
    ``high`` above, then clipped to ``[lower, upper]``. ``c``, ``b``, ``w`` and ``fixed``
    must lie within those limits (to :data:`REFERENCE_TOLERANCE`); the law between them
    may leave them (Algorithm 3's jump at ``mga`` opens past ``w``), hence the clip.

    Attributes:
        c: Close preshape, hand-joint order.
        b: Base open configuration.
        w: Widest open configuration.
        u: Pose uncertainty in [0, 1].
        mga: Normalised distance of maximum grip aperture, in [MGA_MIN, 1] (0.01).
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
    rotation_weight: float = ROTATION_WEIGHT  # [m/rad]
    fixed: np.ndarray | None = None
    arrival: np.ndarray = field(init=False, repr=False, compare=False)
    low_slope: np.ndarray = field(init=False, repr=False, compare=False)
    high: np.ndarray = field(init=False, repr=False, compare=False)
    clip_low: bool = field(init=False, repr=False, compare=False)
    fixed_clipped: np.ndarray | None = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        for name in ("continuous", "open_arrival"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise ConfigError(f"hand.{name}", getattr(self, name), "true or false")
            object.__setattr__(self, name, bool(getattr(self, name)))
        for name in ("u", "mga", "rotation_weight"):
            value = getattr(self, name)
            if not is_number(value):
                raise ConfigError(f"hand.{name}", value, "a number")
        arrays = {}
        for name in ("c", "b", "w", "lower", "upper"):
            try:
                value = np.array(getattr(self, name), dtype=float)
            except (TypeError, ValueError):
                value = np.full(2, np.nan)
            if value.ndim != 1 or not np.all(np.isfinite(value)):
                raise ConfigError(f"hand.{name}", getattr(self, name), "a finite list of numbers")
            arrays[name] = value
        n = arrays["lower"].size
        if arrays["upper"].size != n or np.any(arrays["lower"] > arrays["upper"]):
            raise ConfigError(
                "hand.lower, hand.upper",
                (arrays["lower"].tolist(), arrays["upper"].tolist()),
                "limits of one length with lower <= upper",
            )
        for name in ("c", "b", "w"):
            if arrays[name].size != n:
                raise ConfigError(
                    f"hand.{name}", arrays[name].tolist(), f"{n} values, one per hand joint"
                )
        if self.fixed is not None:
            fixed = floats(self.fixed)
            if fixed is None or fixed.shape != (n,) or not np.all(np.isfinite(fixed)):
                raise ConfigError("hand.fixed", shown(self.fixed), f"{n} finite values")
            object.__setattr__(self, "fixed", fixed)
        lower, upper = arrays["lower"], arrays["upper"]
        references = [(name, arrays[name]) for name in ("c", "b", "w")]
        if self.fixed is not None:
            references.append(("fixed", self.fixed))
        for name, value in references:
            outside = np.flatnonzero(
                (value < lower - REFERENCE_TOLERANCE) | (value > upper + REFERENCE_TOLERANCE)
            )
            if outside.size:
                k = int(outside[0])
                raise ConfigError(
                    f"hand.{name}",
                    value.tolist(),
                    f"values within the hand joints' limits (joint {k}: "
                    f"[{lower[k]:.6g}, {upper[k]:.6g}])",
                )
        if self.distance not in DISTANCE_KINDS:
            raise ConfigError("hand.distance", self.distance, f"one of {DISTANCE_KINDS}")
        weight = _check_weight("hand.rotation_weight", self.rotation_weight)
        object.__setattr__(self, "rotation_weight", weight)
        for name, value in arrays.items():
            value.flags.writeable = False
            object.__setattr__(self, name, value)
        object.__setattr__(self, "u", _check_unit("hand.u", self.u))
        object.__setattr__(self, "mga", _check_unit("hand.mga", self.mga, low=MGA_MIN))
        c, b, w = arrays["c"], arrays["b"], arrays["w"]
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
        """Hand configuration at normalised distance ``d`` (finite, ``>= 0``), clipped to
        the joint limits."""
        d = _check_distance(d)
        if self.fixed_clipped is not None:
            return self.fixed_clipped.copy()
        if d > self.mga:
            return self.high.copy()
        return np.clip(self.arrival + d * self.low_slope, self.lower, self.upper)

    def batch(self, d: np.ndarray) -> np.ndarray:
        """Hand configurations for a vector of finite distances ``>= 0``: shape
        ``(len(d), size)``.

        Args:
            d: Normalised distances (Algorithm 1), finite and ``>= 0``.

        Returns:
            Hand joint values [rad or m], shape ``(len(d), size)``.

        Raises:
            ConfigError: ``d`` is not a vector of finite numbers ``>= 0``.
        """
        values = floats(d)
        if values is None or values.ndim != 1 or not np.all(np.isfinite(values) & (values >= 0)):
            raise ConfigError("d", shown(d), "a vector of finite normalised distances >= 0")
        return self.columns(values).T

    def columns(self, d: np.ndarray) -> np.ndarray:
        """Hand configurations for a vector of distances as the columns of an array of
        shape ``(size, len(d))``: :meth:`batch` transposed, without its check of ``d``
        (the planner's hot path, given the distances it computed; the low branch is
        clipped to the joint limits only if it leaves them on ``[0, mga]``, so a negative
        ``d`` may be extrapolated beyond them).

        Args:
            d: Normalised distances (Algorithm 1).

        Returns:
            Hand joint values [rad or m], shape ``(size, len(d))``.
        """
        d = np.asarray(d, dtype=float)
        if self.fixed_clipped is not None:
            return np.repeat(self.fixed_clipped[:, None], d.size, axis=1)
        hands = np.multiply.outer(self.low_slope, d)
        hands += self.arrival[:, None]
        if self.clip_low:
            np.clip(hands, self.lower[:, None], self.upper[:, None], out=hands)
        above = d > self.mga
        if above.any():
            hands[:, above] = self.high[:, None]
        return hands

    @classmethod
    def from_table(
        cls,
        table: Mapping[str, Any],
        lower: np.ndarray,
        upper: np.ndarray,
        where: str = "hand",
        ignore: Sequence[str] = (),
    ) -> HandLaw:
        """Build a law from a table: a scene's or robot's ``[hand]`` merged onto defaults,
        or a plan file's ``hand_law``. Its keys are the :data:`TABLE_FIELDS`; the values
        are checked once, by the constructor.

        Args:
            table: Field name -> value (``None`` values are left at their default).
            lower: Hand joint lower limits (from the robot model, not the table).
            upper: Hand joint upper limits.
            where: Prefix of error locations (file and table, e.g. ``"scene.toml: hand"``).
            ignore: Further keys to skip (e.g. the plan file's ``start_palm_distance``).

        Returns:
            The law, checked.

        Raises:
            ConfigError: An unknown key (naming the nearest valid one), a missing
                ``c``/``b``/``w``/``u``/``mga``, or a bad value, located at ``where.key``.
        """
        if not isinstance(table, Mapping):
            raise ConfigError(where, table, f"a table with {', '.join(TABLE_FIELDS)}")
        unknown = sorted(set(table) - set(TABLE_FIELDS) - set(ignore))
        if unknown:
            raise unknown_key(where, unknown[0], table[unknown[0]], TABLE_FIELDS)
        given = {k: v for k, v in table.items() if k in TABLE_FIELDS and v is not None}
        missing = [k for k in ("c", "b", "w", "u", "mga") if k not in given]
        if missing:
            raise ConfigError(f"{where}.{missing[0]}", None, f"a {where} table with {missing[0]}")
        try:
            return cls(lower=lower, upper=upper, **given)
        except ConfigError as error:
            key = error.where.removeprefix("hand.")
            raise ConfigError(f"{where}.{key}", error.value, error.expected) from None

    def with_options(self, **changes: object) -> HandLaw:
        """A copy with some fields replaced (e.g. ``u``), validated again
        (``dataclasses.replace``).

        Args:
            **changes: Field name -> new value (e.g. ``u=0.3``, ``fixed=None``).

        Returns:
            The new law.

        Raises:
            ConfigError: A field that is not one of :data:`TABLE_FIELDS` (naming the
                nearest), or a bad value.
        """
        unknown = sorted(set(changes) - set(TABLE_FIELDS))
        if unknown:
            raise unknown_key("hand", unknown[0], changes[unknown[0]], TABLE_FIELDS)
        return dataclasses.replace(self, **changes)  # type: ignore[arg-type]

    def to_dict(self) -> dict[str, object]:
        """The law as written in a plan file (``hand_law``, see the file formats).

        Returns:
            Field name -> value (lists for the arrays), JSON-ready.
        """
        values = {name: getattr(self, name) for name in TABLE_FIELDS}
        return {k: v.tolist() if isinstance(v, np.ndarray) else v for k, v in values.items()}


#: The fields a law table (a scene's ``[hand]``, a plan file's ``hand_law``) may set: every
#: constructor field but the joint limits, which come from the robot model.
TABLE_FIELDS: tuple[str, ...] = tuple(
    f.name for f in dataclasses.fields(HandLaw) if f.init and f.name not in ("lower", "upper")
)


class NormalizedDistance:
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
        rotation_weight: float = ROTATION_WEIGHT,
    ) -> None:
        if distance not in DISTANCE_KINDS:
            raise ConfigError("hand law distance", distance, f"one of {DISTANCE_KINDS}")
        self._rotation_weight = _check_weight("rotation_weight", rotation_weight)
        self._goal = grasp.translation.copy()
        self._goal_rot_t = grasp.rotation.T.copy() if distance == "weighted" else None
        self.start_distance = self.raw(start_placement)
        if self.start_distance <= 1e-9:
            raise ConfigError(
                "start", self.start_distance, "a start whose palm is away from the grasp pose"
            )
        self._inv_start = 1.0 / self.start_distance

    def raw(self, placement: pin.SE3) -> float:
        """Un-normalised distance ``D`` [m] of a palm placement to the grasp.

        Args:
            placement: The palm frame's placement (world frame).

        Returns:
            The distance [m] (plus the weighted rotation [m] with ``distance = "weighted"``).
        """
        return palm_distance(placement, self._goal, self._goal_rot_t, self._rotation_weight)

    def __call__(self, placement: pin.SE3) -> float:
        """Normalised distance ``d`` of a palm placement (0 at the grasp, 1 at the start)."""
        return self.raw(placement) * self._inv_start


#: The old name of :class:`NormalizedDistance`, kept for existing code.
GoalDistance = NormalizedDistance
