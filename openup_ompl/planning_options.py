"""How to plan one problem: :class:`PlanningOptions` (one frozen object, validated once),
the planners accepted by name, and the checks of a run's time limit and seed.

Kept apart from :mod:`openup_ompl.planning` (which builds the OMPL setup and solves) so
that sweeps and the command line can check their options without building a setup.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from ompl import base as ob
from ompl import geometric as og

from openup_ompl import _toml
from openup_ompl.exceptions import ConfigError
from openup_ompl.goal import MAX_RETREAT
from openup_ompl.hand_law import HandLaw
from openup_ompl.ik import IKOptions
from openup_ompl.native import check_mode as check_native_mode
from openup_ompl.planners.ikbirrt import IKBiRRTOptions
from openup_ompl.scene import Problem
from openup_ompl.validity import DEFAULT_RESOLUTION, RESOLUTION_MAX, RESOLUTION_MIN

PlannerFactory = Callable[[ob.SpaceInformation], ob.Planner]

#: OMPL's geometric planners that plan with an :class:`~openup_ompl.goal.IKGoalRegion`
#: (checked in the tests). Left out: PRM and PRMstar sample goals from a second thread,
#: which deadlocks on a Python goal while ``solve()`` holds the GIL; AORRTC segfaults with
#: a Python goal region in OMPL 2.0.1's bindings.
OMPL_PLANNERS: dict[str, PlannerFactory] = {
    "rrtconnect": og.RRTConnect,
    "rrt": og.RRT,
    "rrtstar": og.RRTstar,
    "informedrrtstar": og.InformedRRTstar,
    "sorrtstar": og.SORRTstar,
    "bitstar": og.BITstar,
    "fmt": og.FMT,
    "bfmt": og.BFMT,
    "kpiece1": og.KPIECE1,
    "bkpiece1": og.BKPIECE1,
    "lbkpiece1": og.LBKPIECE1,
}
#: Every planner name :meth:`~openup_ompl.planning.GraspPlanningSetup.solve` accepts.
PLANNERS: tuple[str, ...] = ("ikbirrt", *OMPL_PLANNERS)
_UNSUPPORTED = {
    "prm": "deadlocks on a Python goal region",
    "prmstar": "deadlocks on a Python goal region",
    "aorrtc": "crashes on a Python goal region in OMPL 2.0.1",
}
#: The OMPL classes of :data:`_UNSUPPORTED`, refused as instances too: built by hand they
#: hang or crash the same way (``og.PRMstar`` derives from ``og.PRM``, so it comes first).
_UNSUPPORTED_CLASSES: tuple[tuple[type, str], ...] = (
    (og.PRMstar, "prmstar"),
    (og.PRM, "prm"),
    (og.AORRTC, "aorrtc"),
)


def _hand_override(value: str | Sequence[float] | None, law: HandLaw) -> np.ndarray | None:
    """The fixed hand of ``fixed_hand`` (``None`` for the law), or a :class:`ConfigError`."""
    if value is None:
        return None
    if isinstance(value, str):
        if value not in ("c", "b", "w"):
            raise ConfigError("fixed_hand", value, "'c', 'b', 'w' or a hand configuration")
        return np.asarray(getattr(law, value))
    values = list(value) if isinstance(value, (Sequence, np.ndarray)) else None
    if values is None or not all(_toml.is_number(x) for x in values):
        raise ConfigError(
            "fixed_hand", value, "'c', 'b', 'w' or a hand configuration (a list of numbers)"
        )
    return np.asarray(values, dtype=float)


def check_planner(name: str) -> str:
    """Check a planner name.

    Args:
        name: A planner name, any case.

    Returns:
        ``name`` lowered, one of :data:`PLANNERS`.

    Raises:
        ConfigError: ``name`` is not one of :data:`PLANNERS`; the message says why a
            known but unsupported OMPL planner is left out.
    """
    key = name.lower() if isinstance(name, str) else name
    if key not in PLANNERS:
        why = f" ({_UNSUPPORTED[key]})" if key in _UNSUPPORTED else ""
        raise ConfigError("planner", name, f"one of {list(PLANNERS)}{why}")
    return str(key)


def check_planner_instance(planner: ob.Planner) -> ob.Planner:
    """Check a planner instance.

    Args:
        planner: An OMPL planner.

    Returns:
        ``planner`` itself.

    Raises:
        ConfigError: ``planner`` is an instance of an OMPL planner refused by name (see
            :data:`_UNSUPPORTED`); the message says why.
    """
    for kind, key in _UNSUPPORTED_CLASSES:
        if isinstance(planner, kind):
            raise ConfigError(
                "planner",
                type(planner).__name__,
                f"a planner other than og.PRM, og.PRMstar and og.AORRTC ({_UNSUPPORTED[key]})",
            )
    return planner


#: The longest time limit accepted [s] (about 11.6 days). OMPL 2.0.1's termination
#: condition overflows its clock arithmetic for limits near 1e10 s: it then reports a
#: timeout at once.
TIME_LIMIT_MAX = 1e6


def check_time_limit(time_limit: float, where: str = "time_limit") -> float:
    """Check a planning time limit.

    Args:
        time_limit: Time limit [s].
        where: The name the error gives the value.

    Returns:
        ``time_limit`` as a float [s].

    Raises:
        ConfigError: ``time_limit`` is not a number in ``(0, TIME_LIMIT_MAX]``.
    """
    if not (_toml.is_number(time_limit) and 0 < time_limit <= TIME_LIMIT_MAX):
        raise ConfigError(where, time_limit, f"a positive number of seconds <= {TIME_LIMIT_MAX:g}")
    return float(time_limit)


def check_seed(seed: int | None, where: str = "seed") -> int | None:
    """Check a random seed.

    Args:
        seed: A seed, or ``None`` (fresh entropy).
        where: The name the error gives the value.

    Returns:
        ``seed`` (a Python ``int`` or ``None``).

    Raises:
        ConfigError: ``seed`` is neither ``None`` nor an integer in ``[0, 2^63)``.
    """
    if seed is None:
        return None
    if not (
        isinstance(seed, (int, np.integer))
        and not isinstance(seed, (bool, np.bool_))
        and 0 <= seed < 2**63
    ):
        raise ConfigError(where, seed, "None or an integer in [0, 2^63)")
    return int(seed)


@dataclass(frozen=True)
class PlanningOptions:
    """How to plan one problem, apart from the algorithm (one frozen object, validated once).

    Attributes:
        u: Pose uncertainty in [0, 1] overriding the scene's (``None``: the scene's).
        continuous: Use the law without the jump at ``mga`` (``None``: the scene's).
        open_arrival: Use the law that reaches the grasp opened by ``u`` (an extension,
            see :func:`~openup_ompl.hand_law.open_hand`; ``None``: the scene's).
        fixed_hand: The classical baseline: keep the hand at this configuration (``"c"``,
            ``"b"``, ``"w"`` or joint values) for the whole reach instead of the law.
        resolution: Motion-check resolution [m]: no robot point moves more between two
            checked states (see :data:`~openup_ompl.validity.DEFAULT_RESOLUTION`).
        padding: Margin [m] around obstacles and object, and between the robot's own
            links (up to twice it for a pair: ``collision.self_margins``); default
            ``resolution / 2``, which makes motion checks exact for the unpadded scene.
        planner: Planner name, one of :data:`PLANNERS` (what
            :meth:`~openup_ompl.planning.GraspPlanningSetup.solve` uses when given none).
        time_limit: Planning time [s] (idem).
        simplify: Shorten the path with OMPL's ``PathSimplifier`` (idem).
        simplify_rounds: Rounds of simplification at most.
        ik_options: IK settings (``None``: :class:`~openup_ompl.ik.IKOptions` defaults).
        ikbirrt_options: IKBiRRT settings (its seed is set by the run).
        max_goal_samples: ``maxSampleCount()`` of the goal region.
        planner_range: ``setRange`` [rad, joint-space norm] of the OMPL planners made by
            name. OMPL's default (20 % of the space's extent) measured slower on the shipped
            and test scenes: long coupled motions mostly end in collision.
        pregrasp: The goal region's pregrasp distance [m], at most 1 (see
            :class:`~openup_ompl.goal.IKGoalRegion`): OMPL's planners are given pregrasp
            states, each an IK solution backed off straight against the approach direction,
            and :meth:`~openup_ompl.planning.GraspPlanningSetup.solve` appends the
            certified approach. 0 gives them the grasp configurations themselves. IKBiRRT
            grows its own retreat (``ikbirrt_options.retreat``) and ignores it. The
            default, IKBiRRT's retreat, measured faster with ``rrtconnect`` and the law on
            the problem suites.
        native: The compiled coupled check (:mod:`openup_ompl.native`, built by
            ``openup-ompl build-native``): ``"auto"`` uses it when it is built for the
            pinocchio and coal in use and exact for the law, ``"on"`` requires it,
            ``"off"`` never uses it. The same verdicts and plans either way.
    """

    u: float | None = None
    continuous: bool | None = None
    open_arrival: bool | None = None
    fixed_hand: str | Sequence[float] | None = None
    resolution: float = DEFAULT_RESOLUTION  # [m]
    padding: float | None = None  # [m]
    planner: str = "ikbirrt"
    time_limit: float = 5.0  # [s]
    simplify: bool = False
    simplify_rounds: int = 3
    ik_options: IKOptions | None = None
    ikbirrt_options: IKBiRRTOptions | None = None
    max_goal_samples: int = 25
    planner_range: float = 0.4  # [rad]
    pregrasp: float = 0.1  # [m]
    native: str = "auto"

    def __post_init__(self) -> None:
        if self.u is not None and not (_toml.is_number(self.u) and 0 <= self.u <= 1):
            raise ConfigError("u", self.u, "a number in [0, 1]")
        for name in ("continuous", "open_arrival", "simplify"):
            value = getattr(self, name)
            if value is not None and not isinstance(value, bool):
                raise ConfigError(name, value, "true or false")
        if not (
            _toml.is_number(self.resolution) and RESOLUTION_MIN <= self.resolution <= RESOLUTION_MAX
        ):
            raise ConfigError(
                "resolution",
                self.resolution,
                f"a length in [{RESOLUTION_MIN:g}, {RESOLUTION_MAX:g}] m",
            )
        if self.padding is not None and not (
            _toml.is_number(self.padding) and 0 <= self.padding < math.inf
        ):
            raise ConfigError("padding", self.padding, "a length >= 0 [m]")
        check_planner(self.planner)
        check_time_limit(self.time_limit)
        rounds = self.simplify_rounds
        if not (_toml.is_integer(rounds) and 0 <= rounds <= 1000):
            raise ConfigError("simplify_rounds", rounds, "an integer in [0, 1000]")
        if not (_toml.is_integer(self.max_goal_samples) and 1 <= self.max_goal_samples < 2**31):
            raise ConfigError("max_goal_samples", self.max_goal_samples, "an integer in [1, 2^31)")
        for name in ("simplify_rounds", "max_goal_samples"):  # numpy integers stored as int
            object.__setattr__(self, name, int(getattr(self, name)))
        if not (_toml.is_number(self.planner_range) and 0 < self.planner_range < math.inf):
            raise ConfigError("planner_range", self.planner_range, "a positive step [rad]")
        for name, kind in (("ik_options", IKOptions), ("ikbirrt_options", IKBiRRTOptions)):
            value = getattr(self, name)
            if value is not None and not isinstance(value, kind):
                raise ConfigError(name, value, f"None or an {kind.__name__}")
        _toml.number(self.pregrasp, "pregrasp", low=0.0, high=MAX_RETREAT)
        check_native_mode(self.native)

    def overridden(self, **changes: Any) -> PlanningOptions:
        """These options with some fields replaced.

        Args:
            **changes: New field values; ``None`` keeps the field's.

        Returns:
            New options (checked again), or ``self`` when nothing changes.

        Raises:
            ConfigError: A bad new value.
        """
        given = {name: value for name, value in changes.items() if value is not None}
        return dataclasses.replace(self, **given) if given else self


def planning_law(problem: Problem, options: PlanningOptions) -> HandLaw:
    """The hand law ``problem`` is planned with under ``options``: the scene's, with the
    options' ``u``, variants and fixed hand where they are given.

    Args:
        problem: The planning problem; its scene gives the default law.
        options: The planning options.

    Returns:
        The hand law to plan with.

    Raises:
        ConfigError: A bad ``fixed_hand``.
    """
    changes = {
        key: value
        for key, value in (
            ("u", options.u),
            ("continuous", options.continuous),
            ("open_arrival", options.open_arrival),
        )
        if value is not None
    }
    fixed = _hand_override(options.fixed_hand, problem.hand_law)
    return problem.hand_law.with_options(**changes, fixed=fixed)
