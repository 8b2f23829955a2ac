"""GraspPlanningSetup: a reach-to-grasp problem wired into a real ``og.SimpleSetup``.

The arm joints are the state space; :class:`~openup_ompl.validity.CoupledValidityChecker`
and :class:`~openup_ompl.validity.CoupledMotionValidator` check every state with the hand
set by the law; the goal is an :class:`~openup_ompl.goal.IKGoalRegion`. Any OMPL planner
that accepts sampleable goals can be plugged into :attr:`GraspPlanningSetup.simple_setup`.

The setup is built from :mod:`~openup_ompl.ompl_setup` (state space, checks, start) and
the options of :mod:`~openup_ompl.planning_options`; a solution becomes a plan through
the checks of :mod:`~openup_ompl.solution_check`.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
from ompl import base as ob
from ompl import geometric as og

from openup_ompl.exceptions import ConfigError, InvalidProblem, PlanningFailed
from openup_ompl.goal import GOAL_THRESHOLD, GraspGoal, IKGoalRegion
from openup_ompl.ik import IKOptions, IKSolver
from openup_ompl.ompl_setup import arm_state_space, coupled_simple_setup, set_start
from openup_ompl.plan import Plan
from openup_ompl.plan_checks import number_rows
from openup_ompl.planners.ikbirrt import IKBiRRT, IKBiRRTOptions
from openup_ompl.planning_options import (
    OMPL_PLANNERS,
    PLANNERS,
    TIME_LIMIT_MAX,
    PlanningOptions,
    check_planner,
    check_planner_instance,
    check_seed,
    check_time_limit,
    planning_law,
)
from openup_ompl.scene import Problem
from openup_ompl.solution_check import densify, rows_to_verify, verify_path
from openup_ompl.validity import CoupledChecker

__all__ = [
    "OMPL_PLANNERS",
    "PLANNERS",
    "RESTARTED_PLANNERS",
    "STALL_MOTIONS",
    "TIME_LIMIT_MAX",
    "GraspPlanningSetup",
    "PlanningOptions",
    "arm_state_space",
    "check_planner",
    "check_planner_instance",
    "check_seed",
    "check_time_limit",
]

#: The planners made by name that :meth:`GraspPlanningSetup.solve` restarts when their goal
#: tree is stuck. OMPL's RRTConnect draws a new goal only while its goal tree holds more
#: than twice the goals drawn, so a goal from which every step collides (a pregrasp state
#: deep in a drawer) never grows its tree and no other goal is ever drawn: the run waits
#: out its limit.
RESTARTED_PLANNERS = ("rrtconnect",)
#: Motions checked since the last goal was drawn after which such a run is restarted (its
#: trees cleared, a new goal drawn): above what solved `rrtconnect` runs check between two
#: draws, below what runs stuck on one goal check within a 5 s limit.
STALL_MOTIONS = 2500


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
        NativeUnavailable: ``native="on"`` and the compiled check is unavailable.

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
        native: str | None = None,
    ) -> None:
        if options is None:
            options = PlanningOptions()
        elif not isinstance(options, PlanningOptions):
            options = PlanningOptions(u=options)
        options = options.overridden(
            u=u,
            continuous=continuous,
            open_arrival=open_arrival,
            fixed_hand=fixed_hand,
            resolution=resolution,
            padding=padding,
            ik_options=ik_options,
            ikbirrt_options=ikbirrt_options,
            max_goal_samples=max_goal_samples,
            planner_range=planner_range,
            pregrasp=pregrasp,
            planner=planner,
            time_limit=time_limit,
            simplify=simplify,
            simplify_rounds=simplify_rounds,
            native=native,
        )
        if not isinstance(problem, Problem):
            raise ConfigError("problem", problem, "a Problem (load_scene(path))")
        self.options = options
        self.planner_range = float(options.planner_range)
        self.problem = problem
        self.law = planning_law(problem, options)
        self.ikbirrt_options = options.ikbirrt_options or IKBiRRTOptions()
        self.space = arm_state_space(problem.robot)
        self.checker = CoupledChecker(
            problem,
            self.law,
            resolution=options.resolution,
            padding=options.padding,
            native=options.native,
        )
        self.simple_setup, self.validity_checker, self.motion_validator = coupled_simple_setup(
            self.space, self.checker
        )
        self.space_information = self.simple_setup.getSpaceInformation()
        set_start(self.simple_setup, problem, self.checker)
        self._set_goal()

    def _set_goal(self) -> None:
        """The IK solver of the grasp pose, the goal and its OMPL region, set on the setup.

        Raises:
            InvalidProblem: The start is already at the grasp pose.
            UnreachableGrasp: No collision-free IK solution of the grasp pose was found.
        """
        problem = self.problem
        self.ik = IKSolver(problem.robot, problem.grasp, self.options.ik_options)
        self._goal_rng_seed = 0
        self.goal = GraspGoal(self.checker, self.ik, np.random.default_rng(self._goal_rng_seed))
        start_distance = self.goal.task_error(problem.start)
        if start_distance <= GOAL_THRESHOLD:
            raise InvalidProblem(
                f"start is already at the grasp pose (task-space distance {start_distance:.2e} m)"
            )
        self.goal_region = IKGoalRegion(
            self.space_information,
            self.goal,
            max_samples=self.options.max_goal_samples,
            pregrasp=self.options.pregrasp,
            pregrasp_step=self.ikbirrt_options.retreat_step,
            max_joint_step=self.ikbirrt_options.max_step,
        )
        self._initial_solutions = list(self.goal.solutions)
        self.simple_setup.setGoal(self.goal_region)

    def make_planner(self, name: str, seed: int | None = None) -> ob.Planner:
        """A planner by name (see :data:`PLANNERS`) on this setup's space information.

        Args:
            name: A planner name from :data:`PLANNERS` (any case).
            seed: Seed of an IKBiRRT (``None``: fresh entropy); OMPL's planners ignore it.

        Returns:
            The planner, its range set to :attr:`planner_range` [rad] when it has one.

        Raises:
            ConfigError: ``name`` is not one of :data:`PLANNERS`.
        """
        key = check_planner(name)
        si = self.space_information
        if key == "ikbirrt":
            return IKBiRRT(si, dataclasses.replace(self.ikbirrt_options, seed=seed))
        planner = OMPL_PLANNERS[key](si)
        if hasattr(planner, "setRange"):
            planner.setRange(self.planner_range)
        return planner

    def reseed(self, seed: int | None) -> None:
        """Restart the run's random generators (IK restarts, goal sampling) from ``seed``.

        Args:
            seed: A non-negative integer seed, or ``None`` to draw one
                (:func:`check_seed`).

        Raises:
            ConfigError: ``seed`` is not a valid seed.
        """
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

        Returns:
            The verified :class:`~openup_ompl.plan.Plan`: full configurations from the
            start to the grasp, with its planning statistics.
        """
        time_limit = self.options.time_limit if time_limit is None else check_time_limit(time_limit)
        seed = check_seed(seed)
        planner = self.options.planner if planner is None else planner
        # Checked as the options are.
        options = self.options.overridden(simplify=simplify, simplify_rounds=simplify_rounds)
        instance, seed = self._planner_for(planner, seed)
        self.reseed(seed)
        ss = self.simple_setup
        try:
            ss.setPlanner(instance)
        except RuntimeError as error:  # OMPL: "Planner instance does not match space ..."
            raise ConfigError(
                "planner", type(instance).__name__, f"a planner on space_information ({error})"
            ) from None
        ss.clear()
        counts = self._counts()
        restarting = isinstance(planner, str) and planner.lower() in RESTARTED_PLANNERS
        started = time.perf_counter()
        status, restarts = self._run(started + float(time_limit), restarting)
        solve_time = time.perf_counter() - started
        name = instance.getName()
        status_text = status.getStatus().name.lower().replace("_", " ")
        if status != ob.PlannerStatus.EXACT_SOLUTION or not ss.haveExactSolutionPath():
            raise PlanningFailed(status_text, name, time_limit)
        approach = self._append_approach(ss.getSolutionPath())
        if options.simplify:
            self.simplify(ss.getSolutionPath(), options.simplify_rounds)
        dof = self.problem.robot.arm_idx.size
        waypoints = np.array([s[0:dof] for s in ss.getSolutionPath().getStates()])
        stats = self._run_stats(counts, instance, waypoints, approach)
        if restarting:
            stats["restarts"] = restarts
        path, segment = densify(self.checker, waypoints)
        rows = rows_to_verify(self.checker, waypoints, segment)
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

    def _planner_for(
        self, planner: str | ob.Planner, seed: int | None
    ) -> tuple[ob.Planner, int | None]:
        """The planner instance of a run and the run's seed: a planner by name is made
        with ``seed``; an IKBiRRT instance is seeded with it, or keeps its own
        (``options.seed``) when ``seed`` is ``None``."""
        if not isinstance(planner, ob.Planner):
            return self.make_planner(planner, seed), seed
        instance = check_planner_instance(planner)
        if isinstance(instance, IKBiRRT):
            # Without a seed here the run takes the instance's own (its options'): an
            # IKBiRRT built with seed=3 repeats its path from call to call.
            seed = instance.options.seed if seed is None else seed
            instance.set_seed(seed)
        return instance, seed

    def _counts(self) -> tuple[int, int, int]:
        """The counters a run's statistics are differences of: states and motions checked,
        IK calls."""
        return self.checker.states_checked, self.checker.motions_checked, self.ik.calls

    def _run(self, deadline: float, restarting: bool) -> tuple[ob.PlannerStatus, int]:
        """Run the setup's planner until ``deadline`` (a ``time.perf_counter()`` value),
        restarting it when stalled if ``restarting``; the status and the restarts made."""
        # The goal set on the setup (a user's own IKGoalRegion too) stops offering goals
        # at the time limit, which planners that draw them all up front do not watch.
        goal = self.simple_setup.getGoal()
        region = goal if isinstance(goal, IKGoalRegion) else None
        if region is not None:
            region.deadline = deadline
        try:
            if restarting:
                return self._solve_restarting(deadline)
            # OMPL's solve(seconds) times a limit of 1 s or more in a thread it starts and
            # joins on every call; the condition is checked inline here instead.
            limit = max(deadline - time.perf_counter(), 0.0)
            return self.simple_setup.solve(ob.timedPlannerTerminationCondition(limit)), 0
        finally:
            if region is not None:
                region.deadline = None

    def _run_stats(
        self,
        before: tuple[int, int, int],
        instance: ob.Planner,
        waypoints: np.ndarray,
        approach: int,
    ) -> dict[str, Any]:
        """The counters of a run (checks and IK calls since ``before``, IKBiRRT's own)."""
        states, motions, ik_calls = self._counts()
        stats: dict[str, Any] = {
            "state_checks": states - before[0],
            "motion_checks": motions - before[1],
            "ik_calls": ik_calls - before[2],
            "waypoints": int(waypoints.shape[0]),
            "approach_states": approach,
            "resolution": self.checker.resolution,  # [m] what a re-validation checks with
            "padding": self.checker.world.padding,  # [m]
        }
        if isinstance(instance, IKBiRRT):
            stats.update(
                iterations=instance.iterations,
                goal_roots=instance.goal_roots,
                retreat_vertices=instance.retreat_vertices,
                lazy_cuts=instance.lazy_cuts,
                start_tree=instance.start_tree_size,
                goal_tree=instance.goal_tree_size,
            )
        return stats

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
        """Shorten ``path`` in place with OMPL's ``PathSimplifier``, in bounded rounds.

        Args:
            path: An OMPL path over the arm joints [rad], changed in place.
            rounds: Rounds at most; stops early when a round changes nothing.
        """
        simplifier = og.PathSimplifier(self.space_information, self.goal_region)
        for _ in range(rounds):
            changed = simplifier.reduceVertices(path)
            changed = simplifier.partialShortcutPath(path) or changed
            changed = simplifier.collapseCloseVertices(path) or changed
            if not changed:
                break

    def densify(self, waypoints: np.ndarray) -> np.ndarray:
        """Full configurations along the waypoints at the checker's resolution, the hand
        from the law at every row.

        Args:
            waypoints: Arm configurations [rad], shape ``(M, dof)``.

        Returns:
            Full configurations [rad; m for prismatic joints], shape ``(N, nq)``,
            ``N >= M``.

        Raises:
            ConfigError: ``waypoints`` is not a non-empty array of rows of ``dof`` finite
                numbers.
        """
        dof = self.problem.robot.arm_idx.size
        return densify(self.checker, number_rows(waypoints, "waypoints", dof))[0]

    def verify(self, path: np.ndarray, rows: np.ndarray | None = None) -> None:
        """Refuse a path that is not a valid plan: it must start at the start, end on the
        grasp pose within the goal threshold, keep every arm and hand joint within its
        limits (:data:`~openup_ompl.robot.LIMIT_TOLERANCE`) at every row, and collide
        nowhere (at ``rows`` only, if given: :meth:`solve` leaves out the rows inside
        motions the checker certified). Whether the hand follows the law is not checked.

        Args:
            path: Full configurations [rad; m for prismatic joints], shape ``(N, nq)``.
            rows: Indices into ``path`` of the rows to check for collision (``None``: all).

        Raises:
            ConfigError: ``path`` is not a non-empty array of rows of ``nq`` finite
                numbers, or ``rows`` holds an index outside it.
            VerifyFailed: With the reason; never expected from a correct planner.
        """
        verify_path(self.problem, self.checker, self.goal.task_error, path, rows)
