"""GraspPlanningSetup: a reach-to-grasp problem wired into a real ``og.SimpleSetup``.

The arm joints are the state space; :class:`~openup_ompl.validity.CoupledValidityChecker`
and :class:`~openup_ompl.validity.CoupledMotionValidator` check every state with the hand
set by the law; the goal is an :class:`~openup_ompl.goal.IKGoalRegion`. Any OMPL planner
that accepts sampleable goals can be plugged into :attr:`GraspPlanningSetup.simple_setup`.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from ompl import base as ob
from ompl import geometric as og

from openup_ompl import _toml
from openup_ompl.exceptions import ConfigError, InvalidProblem, PlanningFailed, VerifyFailed
from openup_ompl.goal import GOAL_THRESHOLD, MAX_RETREAT, GraspGoal, IKGoalRegion
from openup_ompl.hand_law import HandLaw
from openup_ompl.ik import IKOptions, IKSolver
from openup_ompl.plan import Plan, number_rows
from openup_ompl.planners.ikbirrt import IKBiRRT, IKBiRRTOptions
from openup_ompl.robot import LIMIT_TOLERANCE, Robot
from openup_ompl.scene import Problem
from openup_ompl.validity import (
    DEFAULT_RESOLUTION,
    RESOLUTION_MAX,
    RESOLUTION_MIN,
    CoupledChecker,
    CoupledMotionValidator,
    CoupledValidityChecker,
)

PlannerFactory = Callable[[ob.SpaceInformation], ob.Planner]

#: OMPL's geometric planners that plan with an :class:`IKGoalRegion` (checked in the
#: tests). Left out: PRM and PRMstar sample goals from a second thread, which deadlocks on
#: a Python goal while ``solve()`` holds the GIL; AORRTC segfaults with a Python goal
#: region in OMPL 2.0.1's bindings.
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
#: Every planner name :meth:`GraspPlanningSetup.solve` accepts.
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
    """``name`` lowered if it is one of :data:`PLANNERS`, else a :class:`ConfigError` that
    says why a known but unsupported OMPL planner is left out."""
    key = name.lower() if isinstance(name, str) else name
    if key not in PLANNERS:
        why = f" ({_UNSUPPORTED[key]})" if key in _UNSUPPORTED else ""
        raise ConfigError("planner", name, f"one of {list(PLANNERS)}{why}")
    return str(key)


def check_planner_instance(planner: ob.Planner) -> ob.Planner:
    """``planner`` unless it is an instance of an OMPL planner refused by name (see
    :data:`_UNSUPPORTED`), else a :class:`ConfigError` that says why."""
    for kind, key in _UNSUPPORTED_CLASSES:
        if isinstance(planner, kind):
            raise ConfigError(
                "planner",
                type(planner).__name__,
                f"a planner other than og.PRM, og.PRMstar and og.AORRTC ({_UNSUPPORTED[key]})",
            )
    return planner


def arm_state_space(robot: Robot) -> ob.RealVectorStateSpace:
    """OMPL's state space of a robot's arm joints, bounded by their limits."""
    dof = robot.arm_idx.size
    space = ob.RealVectorStateSpace(dof)
    bounds = ob.RealVectorBounds(dof)
    for i, (low, high) in enumerate(zip(robot.arm_lower, robot.arm_upper, strict=True)):
        bounds.setLow(i, float(low))
        bounds.setHigh(i, float(high))
    space.setBounds(bounds)
    return space


#: The planners made by name that :meth:`GraspPlanningSetup.solve` restarts when their goal
#: tree is stuck. OMPL's RRTConnect draws a new goal only while its goal tree holds more
#: than twice the goals drawn, so a goal from which every step collides (a pregrasp state
#: deep in a drawer) never grows its tree and no other goal is ever drawn: the run waits
#: out its limit.
RESTARTED_PLANNERS = ("rrtconnect",)
#: Motions checked since the last goal was drawn after which such a run is restarted (its
#: trees cleared, a new goal drawn). Solved `rrtconnect` runs of the three suites and of
#: six unseen Panda scenes (5 seeds each) went at most 1,616 motions between two draws;
#: runs stuck on one goal 7,100-9,700 in 5 s.
STALL_MOTIONS = 2500

#: The longest time limit accepted [s] (about 11.6 days). OMPL 2.0.1's termination
#: condition overflows its clock arithmetic for limits near 1e10 s: it then reports a
#: timeout at once.
TIME_LIMIT_MAX = 1e6


def check_time_limit(time_limit: float, where: str = "time_limit") -> float:
    """``time_limit`` [s] if it is a number in ``(0, TIME_LIMIT_MAX]``, else a
    :class:`ConfigError`."""
    if not (_toml.is_number(time_limit) and 0 < time_limit <= TIME_LIMIT_MAX):
        raise ConfigError(where, time_limit, f"a positive number of seconds <= {TIME_LIMIT_MAX:g}")
    return float(time_limit)


def check_seed(seed: int | None, where: str = "seed") -> int | None:
    """``seed`` if it is ``None`` or an integer in ``[0, 2^63)``, else a
    :class:`ConfigError`."""
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
        planner: Planner name, one of :data:`PLANNERS` (what :meth:`GraspPlanningSetup.solve`
            uses when given none).
        time_limit: Planning time [s] (idem).
        simplify: Shorten the path with OMPL's ``PathSimplifier`` (idem).
        simplify_rounds: Rounds of simplification at most.
        ik_options: IK settings (``None``: :class:`~openup_ompl.ik.IKOptions` defaults).
        ikbirrt_options: IKBiRRT settings (its seed is set by the run).
        max_goal_samples: ``maxSampleCount()`` of the goal region.
        planner_range: ``setRange`` [rad, joint-space norm] of the OMPL planners made by
            name. OMPL's default (20 % of the space's extent, 2.6 rad on the Panda) measured
            2-8x slower in median solve time on the shipped and test scenes: long coupled
            motions mostly end in collision.
        pregrasp: The goal region's pregrasp distance [m], at most 1 (see
            :class:`~openup_ompl.goal.IKGoalRegion`): OMPL's planners are given pregrasp
            states, each an IK solution backed off straight against the approach direction,
            and :meth:`GraspPlanningSetup.solve` appends the certified approach. 0 gives
            them the grasp configurations themselves. IKBiRRT grows its own retreat
            (``ikbirrt_options.retreat``) and ignores it. The default, IKBiRRT's retreat,
            measured 3.8x (Panda) and 2.9x (LWA3) faster in median solve time with
            ``rrtconnect`` and the law on the problem suites, level on the UR5 + Allegro.
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

    def overridden(self, **changes: Any) -> PlanningOptions:
        """These options with the fields of ``changes`` that are not ``None`` replaced
        (checked again); ``self`` when there are none."""
        given = {name: value for name, value in changes.items() if value is not None}
        return dataclasses.replace(self, **given) if given else self


class GraspPlanningSetup:
    """A reach-to-grasp problem on OMPL: state space, coupled checks, IK goal, planners.

    Args:
        problem: The loaded scene (:func:`~openup_ompl.scene.load_scene`).
        options: The :class:`PlanningOptions` (a number is taken as ``u``, the old
            positional form).
        **changes: Fields of :class:`PlanningOptions` overriding ``options`` (the keyword
            form, e.g. ``GraspPlanningSetup(problem, u=0.3, fixed_hand="w")``); ``None``
            values are ignored.

    Raises:
        ConfigError: A bad option.
        InvalidProblem: The start collides, or is already at the grasp pose.
        UnreachableGrasp: No collision-free IK solution of the grasp pose was found.

    Attributes:
        problem: The problem as given.
        options: The :class:`PlanningOptions` in force (the keywords applied).
        law: The hand law planned with (the problem's, with the options' ``u``,
            variants and fixed hand).
        simple_setup: The ``og.SimpleSetup``; plug any OMPL planner into it.
        space_information: Its ``ob.SpaceInformation`` (build planners on it).
        checker: The numpy-level coupled check (counters of checks live there).
        ik: The palm-frame :class:`~openup_ompl.ik.IKSolver` of the grasp pose.
        goal: The :class:`~openup_ompl.goal.GraspGoal` (IK solutions found so far).
        goal_region: The ``IKGoalRegion`` set as the problem's goal.
    """

    def __init__(
        self,
        problem: Problem,
        options: PlanningOptions | float | None = None,
        *,
        u: float | None = None,
        continuous: bool | None = None,
        open_arrival: bool | None = None,
        fixed_hand: str | Sequence[float] | None = None,
        resolution: float | None = None,
        padding: float | None = None,
        ik_options: IKOptions | None = None,
        ikbirrt_options: IKBiRRTOptions | None = None,
        max_goal_samples: int | None = None,
        planner_range: float | None = None,
        pregrasp: float | None = None,
        planner: str | None = None,
        time_limit: float | None = None,
        simplify: bool | None = None,
        simplify_rounds: int | None = None,
    ) -> None:
        if options is None:
            options = PlanningOptions()
        elif not isinstance(options, PlanningOptions):
            options = PlanningOptions(u=options)
        changes: dict[str, Any] = {
            "u": u,
            "continuous": continuous,
            "open_arrival": open_arrival,
            "fixed_hand": fixed_hand,
            "resolution": resolution,
            "padding": padding,
            "ik_options": ik_options,
            "ikbirrt_options": ikbirrt_options,
            "max_goal_samples": max_goal_samples,
            "planner_range": planner_range,
            "pregrasp": pregrasp,
            "planner": planner,
            "time_limit": time_limit,
            "simplify": simplify,
            "simplify_rounds": simplify_rounds,
        }
        options = options.overridden(**changes)
        if not isinstance(problem, Problem):
            raise ConfigError("problem", problem, "a Problem (load_scene(path))")
        self.options = options
        self.planner_range = float(options.planner_range)
        self.problem = problem
        robot = problem.robot
        law_changes = {
            k: v
            for k, v in (
                ("u", options.u),
                ("continuous", options.continuous),
                ("open_arrival", options.open_arrival),
            )
            if v is not None
        }
        self.law = problem.hand_law.with_options(
            **law_changes, fixed=_hand_override(options.fixed_hand, problem.hand_law)
        )
        self.ikbirrt_options = options.ikbirrt_options or IKBiRRTOptions()
        resolution = options.resolution
        dof = robot.arm_idx.size
        space = arm_state_space(robot)
        self.space = space
        self.simple_setup = og.SimpleSetup(space)
        si = self.simple_setup.getSpaceInformation()
        self.space_information = si
        self.checker = CoupledChecker(
            problem, self.law, resolution=resolution, padding=options.padding
        )
        self.validity_checker = CoupledValidityChecker(si, self.checker)
        self.motion_validator = CoupledMotionValidator(si, self.checker)
        self.simple_setup.setStateValidityChecker(self.validity_checker)
        si.setMotionValidator(self.motion_validator)
        # Path length, satisfied by any solution: the optimising planners (RRT*, BIT*,
        # FMT*, ...) return their first exact solution instead of refining until the
        # time limit; the others ignore it.
        objective = ob.PathLengthOptimizationObjective(si)
        objective.setCostThreshold(ob.Cost(math.inf))
        self.simple_setup.setOptimizationObjective(objective)
        # Only OMPL's own interpolation reads this fraction (our validator has its own bound).
        step = resolution / float(np.max(self.checker.motion_weights))
        si.setStateValidityCheckingResolution(min(1.0, step / space.getMaximumExtent()))

        try:
            robot.check_arm(problem.start, "start")
        except ConfigError as error:  # a joint beyond its limits: no plan can leave from it
            raise InvalidProblem(f"start configuration outside the joint limits: {error}") from None
        if not self.checker.is_valid(problem.start):
            world = self.checker.finest_world
            pairs = world.colliding_pairs(self.checker.coupled_q(problem.start))
            raise InvalidProblem(
                f"start configuration {problem.start.tolist()} is in collision: {pairs}"
            )
        start = si.allocState()
        start[0:dof] = problem.start.tolist()
        self.simple_setup.setStartState(start)

        self.ik = IKSolver(robot, problem.grasp, options.ik_options)
        self._goal_rng_seed = 0
        self.goal = GraspGoal(self.checker, self.ik, np.random.default_rng(self._goal_rng_seed))
        start_distance = self.goal.task_error(problem.start)
        if start_distance <= GOAL_THRESHOLD:
            raise InvalidProblem(
                f"start is already at the grasp pose (task-space distance {start_distance:.2e} m)"
            )
        self.goal_region = IKGoalRegion(
            si,
            self.goal,
            max_samples=options.max_goal_samples,
            pregrasp=options.pregrasp,
            pregrasp_step=self.ikbirrt_options.retreat_step,
            max_joint_step=self.ikbirrt_options.max_step,
        )
        self._initial_solutions = list(self.goal.solutions)
        self.simple_setup.setGoal(self.goal_region)

    def make_planner(self, name: str, seed: int | None = None) -> ob.Planner:
        """A planner by name (see :data:`PLANNERS`) on this setup's space information."""
        key = check_planner(name)
        si = self.space_information
        if key == "ikbirrt":
            return IKBiRRT(si, dataclasses.replace(self.ikbirrt_options, seed=seed))
        planner = OMPL_PLANNERS[key](si)
        if hasattr(planner, "setRange"):
            planner.setRange(self.planner_range)
        return planner

    def reseed(self, seed: int | None) -> None:
        """Restart the run's random generators (IK restarts, goal sampling) from ``seed``
        (:func:`check_seed`: ``None`` draws one)."""
        self.goal.rng = np.random.default_rng(check_seed(seed))
        self.goal.solutions[:] = self._initial_solutions
        self.goal_region.forget()

    def solve(
        self,
        time_limit: float | None = None,
        planner: str | ob.Planner | None = None,
        seed: int | None = None,
        simplify: bool | None = None,
        simplify_rounds: int | None = None,
    ) -> Plan:
        """Plan from the start to the grasp; the plan's hand follows the law everywhere.

        Args:
            time_limit: Planning time [s] (``None``: the options').
            planner: A name from :data:`PLANNERS` or an ``ob.Planner`` built on
                :attr:`space_information` (``None``: the options'). ``"rrtconnect"`` by
                name is restarted whenever :data:`STALL_MOTIONS` motions pass without a
                goal drawn (``plan.stats["restarts"]``); an instance runs as given.
            seed: Seeds IK and goal sampling, and IKBiRRT entirely (same seed, same
                path; ``None`` with an IKBiRRT instance: its ``options.seed``, recorded as
                the plan's seed; else fresh entropy). OMPL's own planners draw from OMPL's
                process-wide generator, which only ``ompl.util.RNG.setSeed`` before any
                OMPL object fixes (the command line does that).
            simplify: Shorten the path with OMPL's ``PathSimplifier`` (vertex reduction,
                partial shortcuts, collapse of close vertices, through the coupled motion
                validator); the hand is then re-derived from the law. The work is bounded
                by rounds, not time, so that it is repeatable; its random draws come from
                OMPL's process-wide generator (see ``seed``).
            simplify_rounds: Rounds of simplification at most (stops early when a round
                changes nothing). ``simplify`` and this default to the options'.

        Raises:
            ConfigError: Bad time limit, seed, planner name or simplification option,
                or an instance of a planner refused by name (``og.PRM``, ...).
            PlanningFailed: No exact solution in time (the message gives OMPL's status).
        """
        options = self.options
        time_limit = options.time_limit if time_limit is None else check_time_limit(time_limit)
        seed = check_seed(seed)
        planner = options.planner if planner is None else planner
        # Checked as the options are.
        options = options.overridden(simplify=simplify, simplify_rounds=simplify_rounds)
        simplify, rounds = options.simplify, options.simplify_rounds
        ss = self.simple_setup
        if isinstance(planner, ob.Planner):
            instance = check_planner_instance(planner)
            if isinstance(instance, IKBiRRT):
                # Without a seed here the run takes the instance's own (its options'): an
                # IKBiRRT built with seed=3 repeats its path from call to call.
                seed = instance.options.seed if seed is None else seed
                instance.set_seed(seed)
        else:
            instance = self.make_planner(planner, seed)
        self.reseed(seed)
        try:
            ss.setPlanner(instance)
        except RuntimeError as error:  # OMPL: "Planner instance does not match space ..."
            raise ConfigError(
                "planner", type(instance).__name__, f"a planner on space_information ({error})"
            ) from None
        ss.clear()
        checks_before = self.checker.states_checked
        motions_before = self.checker.motions_checked
        ik_before = self.ik.calls
        started = time.perf_counter()
        restarts = 0
        restarting = isinstance(planner, str) and planner.lower() in RESTARTED_PLANNERS
        # The goal set on the setup (a user's own IKGoalRegion too) stops offering goals
        # at the time limit, which planners that draw them all up front do not watch.
        goal = ss.getGoal()
        region = goal if isinstance(goal, IKGoalRegion) else None
        if region is not None:
            region.deadline = started + float(time_limit)
        try:
            if restarting:
                status, restarts = self._solve_restarting(started + float(time_limit))
            else:
                # OMPL's solve(seconds) evaluates a limit of 1 s or more in a thread of its
                # own that it starts and joins on every call: 1.3 ms of a 4 ms Panda solve
                # (the held-out wall_over scene, 40 seeds), against 0.02 ms for the same
                # limit checked inline.
                status = ss.solve(ob.timedPlannerTerminationCondition(float(time_limit)))
        finally:
            if region is not None:
                region.deadline = None
        solve_time = time.perf_counter() - started
        name = instance.getName()
        status_text = status.getStatus().name.lower().replace("_", " ")
        if status != ob.PlannerStatus.EXACT_SOLUTION or not ss.haveExactSolutionPath():
            raise PlanningFailed(status_text, name, time_limit)
        dof = self.problem.robot.arm_idx.size
        approach = self._append_approach(ss.getSolutionPath())
        if simplify:
            self.simplify(ss.getSolutionPath(), rounds)
        waypoints = np.array([s[0:dof] for s in ss.getSolutionPath().getStates()])
        stats: dict[str, Any] = {
            "state_checks": self.checker.states_checked - checks_before,
            "motion_checks": self.checker.motions_checked - motions_before,
            "ik_calls": self.ik.calls - ik_before,
            "waypoints": int(waypoints.shape[0]),
            "approach_states": approach,
            "resolution": self.checker.resolution,  # [m] what a re-validation checks with
            "padding": self.checker.world.padding,  # [m]
        }
        if restarting:
            stats["restarts"] = restarts
        if isinstance(instance, IKBiRRT):
            stats.update(
                iterations=instance.iterations,
                goal_roots=instance.goal_roots,
                retreat_vertices=instance.retreat_vertices,
                lazy_cuts=instance.lazy_cuts,
                start_tree=instance.start_tree_size,
                goal_tree=instance.goal_tree_size,
            )
        path, segment = self._densify(waypoints)
        # Rows inside motions the checker certified need no second check; every waypoint
        # row and every row of a motion it did not certify is checked again.
        certified = np.array(
            [
                self.checker.is_certified(a, b)
                for a, b in zip(waypoints[:-1], waypoints[1:], strict=True)
            ]
        )
        waypoint_row = np.r_[segment[1:] != segment[:-1], True]  # each motion's last row
        waypoint_row[0] = True  # the start
        rows = np.flatnonzero(waypoint_row | ~certified[segment])
        stats["verified_rows"] = int(rows.size)
        self.verify(path, rows)
        return Plan(
            path=path,
            waypoints=waypoints,
            status=status_text,
            planner=name,
            seed=seed,
            solve_time_s=solve_time,
            problem=self.problem,
            law=self.law,
            start_palm_distance=self.checker.goal_distance.start_distance,
            stats=stats,
        )

    def _solve_restarting(self, deadline: float) -> tuple[ob.PlannerStatus, int]:
        """Solve until ``deadline`` (a ``time.perf_counter()`` value), restarting the run
        (:meth:`og.SimpleSetup.clear`: trees emptied, a new goal drawn) whenever
        :data:`STALL_MOTIONS` motions pass without a goal drawn; the last status and the
        restarts made."""
        ss, checker, region = self.simple_setup, self.checker, self.goal_region

        def stalled() -> bool:
            return checker.motions_checked - region.motions_at_draw >= STALL_MOTIONS

        ptc = ob.PlannerTerminationCondition(lambda: time.perf_counter() >= deadline or stalled())
        restarts = 0
        while True:
            region.motions_at_draw = checker.motions_checked
            status = ss.solve(ptc)
            exact = status == ob.PlannerStatus.EXACT_SOLUTION
            if exact or time.perf_counter() >= deadline or not stalled():
                return status, restarts
            restarts += 1
            ss.clear()

    def _append_approach(self, path: og.PathGeometric) -> int:
        """Complete an OMPL path that ends at one of the goal region's pregrasp states with
        its certified approach to the grasp; returns the states appended (0 when the path
        already ends at the grasp)."""
        dof = self.problem.robot.arm_idx.size
        last = path.getState(path.getStateCount() - 1)
        approach = self.goal_region.approach(np.array(last[0:dof]))
        scratch = self.space_information.allocState()
        for arm in approach:
            scratch[0:dof] = arm.tolist()
            path.append(scratch)
        return int(approach.shape[0])

    def simplify(self, path: og.PathGeometric, rounds: int = 3) -> None:
        """Shorten ``path`` in place with OMPL's ``PathSimplifier``, in bounded rounds."""
        simplifier = og.PathSimplifier(self.space_information, self.goal_region)
        for _ in range(rounds):
            changed = simplifier.reduceVertices(path)
            changed = simplifier.partialShortcutPath(path) or changed
            changed = simplifier.collapseCloseVertices(path) or changed
            if not changed:
                break

    def densify(self, waypoints: np.ndarray) -> np.ndarray:
        """Full configurations along the waypoints (arm configurations, ``(M, dof)``) at
        the checker's resolution, the hand from the law at every row: ``(N, nq)``.

        Raises:
            ConfigError: ``waypoints`` is not a non-empty array of rows of ``dof`` finite
                numbers.
        """
        dof = self.problem.robot.arm_idx.size
        return self._densify(number_rows(waypoints, "waypoints", dof))[0]

    def _densify(self, waypoints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`densify`, and for each row the index of the motion it ends on (0 for the
        start row)."""
        arms = [waypoints[:1]]
        segment = [np.zeros(1, dtype=np.intp)]
        for i, (a, b) in enumerate(zip(waypoints[:-1], waypoints[1:], strict=True)):
            arms.append(self.checker.interpolate(a, b, weights=self.checker.weights(a, b)))
            segment.append(np.full(arms[-1].shape[0], i, dtype=np.intp))
        path = self.checker.coupled_qs(np.concatenate(arms)).T.copy()
        return path, np.concatenate(segment)

    def verify(self, path: np.ndarray, rows: np.ndarray | None = None) -> None:
        """Refuse a path that is not a valid plan: it must start at the start, end on the
        grasp pose within the goal threshold, keep every arm and hand joint within its
        limits (:data:`~openup_ompl.robot.LIMIT_TOLERANCE`) at every row, and collide
        nowhere (at ``rows`` only, if given: :meth:`solve` leaves out the rows inside
        motions the checker certified). Whether the hand follows the law is not checked.

        Raises:
            ConfigError: ``path`` is not a non-empty array of rows of ``nq`` finite
                numbers, or ``rows`` holds an index outside it.
            VerifyFailed: With the reason; never expected from a correct planner.
        """
        robot = self.problem.robot
        path = number_rows(path, "path", robot.model.nq)
        if rows is not None:
            rows = np.asarray(rows)
            if rows.dtype.kind not in "iu" or np.any((rows < 0) | (rows >= len(path))):
                expected = f"indices of path rows in [0, {len(path)})"
                raise ConfigError("rows", rows.tolist(), expected)
        arms = path[:, robot.arm_idx]
        if not np.allclose(arms[0], self.problem.start, atol=1e-9):
            raise VerifyFailed("the path does not start at the start")
        distance = self.goal.task_error(arms[-1])
        if distance > GOAL_THRESHOLD:
            raise VerifyFailed(f"the path ends {distance:.2e} m from the grasp pose")
        # Every row, whatever ``rows``: the test is a few array operations, and a joint
        # past its limit can still be collision-free (the Panda's first joint at 10 rad).
        columns = np.r_[robot.arm_idx, robot.hand_idx]
        low = robot.model.lowerPositionLimit[columns]
        high = robot.model.upperPositionLimit[columns]
        values = path[:, columns]
        outside = np.argwhere((values < low - LIMIT_TOLERANCE) | (values > high + LIMIT_TOLERANCE))
        if outside.size:
            i, j = (int(k) for k in outside[0])
            joint = [*robot.spec.arm_joints, *robot.hand_joints][j]
            raise VerifyFailed(
                f"path row {i}: joint {joint} at {values[i, j]:.6g}, outside its limits "
                f"[{low[j]:.6g}, {high[j]:.6g}]"
            )
        rows = np.arange(path.shape[0]) if rows is None else np.asarray(rows, dtype=np.intp)
        flags = self.checker.finest_world.batch_in_collision(
            np.asfortranarray(path[rows].T), stop_at_first=False
        )
        if np.any(flags):
            raise VerifyFailed(f"path row {int(rows[np.flatnonzero(flags)[0]])} collides")
