"""Side by side with a peer: pyroboplan's RRT-Connect, our planners and bare OMPL.

For every problem (default: the Panda suite, ``benchmarks/problems/panda/*.toml``) and
seed, interleaved (the order rotates from run to run):

- **ikbirrt** and **rrtconnect**: ``GraspPlanningSetup(problem).solve(time, planner,
  seed)``, the real problem: the hand follows the law, the goal is the grasp pose, its IK
  solutions sampled during planning. Time = ``plan.solve_time_s``; the wall time of the
  whole ``solve()`` (with simplification and the final check) is reported beside it.
- **pyroboplan** (the optional peer, ``pyroboplan.planning.rrt.RRTPlanner`` with
  ``rrt_connect`` and ``bidirectional_rrt``): an easier problem, the hand frozen at the
  open preshape ``w`` and a joint-space goal. It plans in the robot's full ``q`` on our
  Pinocchio model with every joint outside the arm pinned (lower = upper limit = the
  frozen value, so its uniform samples keep the hand at ``w``), on our collision model
  (``CollisionWorld(problem).geometry_model``: the robot, the obstacles and the object,
  the same pairs). Time = the wall time of its ``plan()``. Its path is then re-checked by
  our exact motion check with the hand at ``w`` (``CoupledChecker.check_motion`` over each
  segment): how many of its paths pass is informational.
- **OMPL reference**: ``og.RRTConnect`` in an ``og.SimpleSetup`` over the arm joints, the
  hand at ``w``, the same joint goal, a minimal Python ``StateValidityChecker`` (arm into
  a full ``q``, then ``pin.computeCollisions`` with the naive broadphase manager of a
  ``CollisionWorld``) and OMPL's own discrete motion validator: the "no Python in the
  loop beyond the state check" reference.

The joint goal of the last two is one collision-free IK solution of the grasp with the
hand at ``w`` (``GraspPlanningSetup(problem, fixed_hand="w").goal``, seeded, so the same
for both and from run to run). Both discretise edges in joint space (Euclidean norm)
at ``resolution / |W|`` [rad], where ``W`` are our per-joint displacement bounds
(``CoupledChecker.plateau_weights``, m/rad) and ``resolution`` our motion-check
resolution (6 mm): by Cauchy-Schwarz no robot point then moves more than 6 mm between
two of their checked states, which is what our motion checks certify (ours do it against
obstacles padded by 3 mm, so that the whole motion is proven collision-free; theirs
check the states only). Ours and the OMPL reference extend by at most ``--range``
(0.4 rad, our ``planner_range``) per step; pyroboplan by ``--peer-range`` (2 rad) with a
goal bias of 0.1, the settings of its own RRT-Connect example, under which it does best
(its trees join only when a new node lands within that step of the other tree). Every
planner gets the same time limit; a failed run counts as the time limit.

Reported per problem: solved counts and median times, the ratios pyroboplan / ikbirrt
and pyroboplan / rrtconnect of the medians, and the geometric mean of each over the
problems, against the targets (pyroboplan / ikbirrt >= 10x on every problem, the least
and the problems under it named, and >= 50x as geometric mean, all of ours solved).
Every plan of ours is re-checked by the independent ``tests/recheck.py``.

pyroboplan is optional (see ``benchmarks/README.md`` for the install line: its metadata
pins another ``pin``, so it goes in with ``--no-deps``); without it the script says so in
one line and runs the rest.

Run (about 10 min on 2 idle cores with pyroboplan; at worst problems x seeds x 4 x time)::

    python benchmarks/bench_peers.py
    python benchmarks/bench_peers.py --problems benchmarks/problems/panda/cage.toml \
        --seeds 5 --time 10 --json bench_peers.json
    python benchmarks/bench_peers.py --problems benchmarks/problems/ur5_allegro --seeds 1
"""

from __future__ import annotations

import argparse
import contextlib
import io
import math
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
from ompl import base as ob
from ompl import geometric as og
from ompl import util as ou

sys.path.insert(0, str(Path(__file__).resolve().parent))

import _common  # noqa: E402

import openup_ompl  # noqa: E402
from openup_ompl.benchmark import default_problems_dir, find_problems, problem_id  # noqa: E402
from openup_ompl.collision import CollisionWorld  # noqa: E402
from openup_ompl.planning import arm_state_space  # noqa: E402
from openup_ompl.validity import DEFAULT_RESOLUTION  # noqa: E402

#: Variants in their first-round order.
VARIANTS = ("ikbirrt", "rrtconnect", "pyroboplan", "ompl-reference")
OURS = ("ikbirrt", "rrtconnect")
#: pyroboplan's extension step [rad] and goal bias: the values of its own RRT-Connect
#: example (``examples/example_rrt.py``). Its trees only join when a new node lands within
#: that step of the other tree, so our 0.4 rad leaves it mostly unsolved in 10 s (measured
#: on table_pick, cage, shelf_small), and without the goal bias they rarely meet.
PEER_RANGE = 2.0
PEER_GOAL_BIAS = 0.1
#: The issue's target for the geometric mean of pyroboplan / ikbirrt.
TARGET = 50.0
#: The issue's target for every problem's pyroboplan / ikbirrt.
SCENE_TARGET = 10.0


def pyroboplan_version() -> str | None:
    """The installed pyroboplan's version, ``None`` when its RRT cannot be imported."""
    try:
        import pyroboplan.planning.rrt  # noqa: F401
    except ImportError:
        return None
    return metadata.version("pyroboplan")


class ReferenceChecker(ob.StateValidityChecker):
    """The minimal Python OMPL checker: arm state into a full ``q`` (hand fixed), then one
    Pinocchio + Coal query with the world's naive broadphase manager."""

    def __init__(
        self, si: ob.SpaceInformation, world: CollisionWorld, q: np.ndarray, arm: np.ndarray
    ) -> None:
        super().__init__(si)
        context = world.context()
        self._model, self._data, self._manager = world.model, context.data, context.manager
        self._q = q.copy()
        self._arm = [int(i) for i in arm]
        self.checks = 0

    def isValid(self, state: ob.State) -> bool:  # noqa: N802 - OMPL's name
        self.checks += 1
        q = self._q
        for k, i in enumerate(self._arm):
            q[i] = state[k]
        return not pin.computeCollisions(self._model, self._data, self._manager, q, True)


@dataclass
class Peers:
    """One problem, prepared once: our setup, and the frozen-hand problem of the peers.

    Attributes:
        name: ``<robot>.<scene>``.
        setup: Our setup with the hand law, or the reason it is infeasible.
        fixed: The setup with the hand at ``w``: its goal gives the joint goal, its
            checker the exact re-check of the peers' paths; or the reason it is
            infeasible.
        goal: The joint goal (arm) of the peers.
        q_start, q_goal: Full configurations, hand at ``w``.
        step: Joint-space edge discretisation of the peers [rad].
    """

    name: str
    setup: openup_ompl.GraspPlanningSetup | str
    fixed: openup_ompl.GraspPlanningSetup | str
    goal: np.ndarray | None = None
    q_start: np.ndarray | None = None
    q_goal: np.ndarray | None = None
    step: float = math.nan
    world: CollisionWorld | None = None
    pinned_model: pin.Model | None = None
    reference: og.SimpleSetup | None = field(default=None, repr=False)
    reference_checker: ReferenceChecker | None = field(default=None, repr=False)


def prepare(path: Path, resolution: float, planner_range: float) -> Peers:
    """Build our setup and the peers' frozen-hand problem for one scene file."""
    problem = openup_ompl.load_scene(path)
    setups: list[openup_ompl.GraspPlanningSetup | str] = []
    for fixed_hand in (None, "w"):
        try:
            setups.append(
                openup_ompl.GraspPlanningSetup(
                    problem, fixed_hand=fixed_hand, planner_range=planner_range
                )
            )
        except (openup_ompl.UnreachableGrasp, openup_ompl.InvalidProblem) as error:
            setups.append(f"infeasible: {type(error).__name__}: {error}")
    peers = Peers(problem_id(path), setups[0], setups[1])
    fixed = peers.fixed
    if isinstance(fixed, str):
        return peers
    robot = problem.robot
    hand = fixed.law.fixed_clipped
    goal = fixed.goal.ensure_solution()
    peers.goal = goal.copy()
    peers.q_start = robot.full_q(problem.start, hand)
    peers.q_goal = robot.full_q(goal, hand)
    peers.step = resolution / float(np.linalg.norm(fixed.checker.plateau_weights))
    peers.world = CollisionWorld(problem)
    # pyroboplan samples the whole q uniformly within the model's limits: pin every joint
    # outside the arm at its frozen value.
    pinned = robot.model.copy()
    lower, upper = pinned.lowerPositionLimit.copy(), pinned.upperPositionLimit.copy()
    frozen = np.ones(pinned.nq, dtype=bool)
    frozen[robot.arm_idx] = False
    lower[frozen] = upper[frozen] = peers.q_start[frozen]
    pinned.lowerPositionLimit, pinned.upperPositionLimit = lower, upper
    peers.pinned_model = pinned
    peers.reference, peers.reference_checker = reference_setup(peers, planner_range)
    return peers


def reference_setup(peers: Peers, planner_range: float) -> tuple[og.SimpleSetup, ReferenceChecker]:
    """OMPL RRTConnect on the arm joints, hand fixed, joint goal, OMPL's motion validator."""
    fixed = peers.fixed
    assert not isinstance(fixed, str) and peers.world is not None
    robot = fixed.problem.robot
    dof = robot.arm_idx.size
    space = arm_state_space(robot)
    ss = og.SimpleSetup(space)
    si = ss.getSpaceInformation()
    checker = ReferenceChecker(si, peers.world, peers.q_start, robot.arm_idx)
    ss.setStateValidityChecker(checker)
    # OMPL's DiscreteMotionValidator checks states this fraction of the extent apart.
    si.setStateValidityCheckingResolution(peers.step / space.getMaximumExtent())
    start, goal = si.allocState(), si.allocState()
    start[0:dof] = fixed.problem.start.tolist()
    goal[0:dof] = peers.goal.tolist()
    ss.setStartAndGoalStates(start, goal)
    planner = og.RRTConnect(si)
    planner.setRange(planner_range)
    ss.setPlanner(planner)
    ss.setup()
    return ss, checker


def path_passes(fixed: openup_ompl.GraspPlanningSetup, arms: np.ndarray) -> bool:
    """Whether our exact check (hand at ``w``) accepts every segment of an arm path."""
    checker = fixed.checker
    if not checker.is_valid(arms[0]):
        return False
    return all(checker.check_motion(a, b) for a, b in zip(arms[:-1], arms[1:], strict=True))


def run_ours(
    setup: openup_ompl.GraspPlanningSetup, planner: str, seed: int, time_limit: float
) -> tuple[dict[str, Any], openup_ompl.Plan | None]:
    started = time.perf_counter()
    try:
        plan = setup.solve(time_limit=time_limit, planner=planner, seed=seed)
    except openup_ompl.PlanningFailed as error:
        wall = time.perf_counter() - started
        return {"solved": False, "time_s": time_limit, "wall_s": wall, "error": str(error)}, None
    wall = time.perf_counter() - started
    return {"solved": True, "time_s": plan.solve_time_s, "wall_s": wall}, plan


def run_pyroboplan(
    peers: Peers, seed: int, time_limit: float, peer_range: float = PEER_RANGE
) -> dict[str, Any]:
    from pyroboplan.planning.rrt import RRTPlanner, RRTPlannerOptions

    fixed = peers.fixed
    assert not isinstance(fixed, str) and peers.world is not None
    options = RRTPlannerOptions(
        max_step_size=peers.step,
        max_connection_dist=peer_range,
        rrt_connect=True,
        bidirectional_rrt=True,
        max_planning_time=time_limit,
        goal_biasing_probability=PEER_GOAL_BIAS,
        rng_seed=seed,  # pyroboplan seeds numpy's global generator; ours draw from their own
    )
    planner = RRTPlanner(peers.pinned_model, peers.world.geometry_model, options)
    chatter = io.StringIO()  # pyroboplan prints its outcome: keep stdout for the tables
    started = time.perf_counter()
    with contextlib.redirect_stdout(chatter):
        path = planner.plan(peers.q_start.copy(), peers.q_goal.copy())
    wall = time.perf_counter() - started
    solved = bool(path)
    result: dict[str, Any] = {
        "solved": solved,
        "time_s": wall if solved else time_limit,
        "wall_s": wall,
        "message": chatter.getvalue().strip().splitlines()[-1:],
    }
    if solved:
        arms = np.array(path)[:, fixed.problem.robot.arm_idx]
        ends = np.allclose(arms[0], fixed.problem.start) and np.allclose(arms[-1], peers.goal)
        result.update(waypoints=len(path), valid=bool(ends and path_passes(fixed, arms)))
    return result


def run_reference(peers: Peers, time_limit: float) -> dict[str, Any]:
    ss, checker = peers.reference, peers.reference_checker
    assert ss is not None and checker is not None
    fixed = peers.fixed
    assert not isinstance(fixed, str)
    ss.clear()
    checks_before = checker.checks
    started = time.perf_counter()
    # The limit checked inline, as GraspPlanningSetup.solve does (OMPL's solve(seconds)
    # starts and joins a thread per call for limits of 1 s or more).
    status = ss.solve(ob.timedPlannerTerminationCondition(float(time_limit)))
    wall = time.perf_counter() - started
    solved = status == ob.PlannerStatus.EXACT_SOLUTION and ss.haveExactSolutionPath()
    result: dict[str, Any] = {
        "solved": bool(solved),
        "time_s": wall if solved else time_limit,
        "wall_s": wall,
        "state_checks": checker.checks - checks_before,
    }
    if solved:
        dof = fixed.problem.robot.arm_idx.size
        arms = np.array([[s[i] for i in range(dof)] for s in ss.getSolutionPath().getStates()])
        result.update(waypoints=len(arms), valid=path_passes(fixed, arms))
    return result


def run_peers(
    paths: Sequence[str | Path],
    seeds: Sequence[int],
    time_limit: float,
    variants: Sequence[str] = VARIANTS,
    planner_range: float = 0.4,
    peer_range: float = PEER_RANGE,
    resolution: float = DEFAULT_RESOLUTION,
    progress: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """Run the comparison; returns the runs, per-problem summaries and our plans.

    Args:
        paths: Scene files or directories of them.
        seeds: One run of every variant per seed.
        time_limit: Per run [s].
        variants: Some of :data:`VARIANTS` (``pyroboplan`` needs it installed).
        planner_range: Largest extension step of ours and of the OMPL reference [rad].
        peer_range: pyroboplan's ``max_connection_dist`` [rad].
        resolution: Our motion-check resolution [m], from which the peers' edge
            discretisation follows.
        progress: Called with one line per run.
    """
    say = progress or (lambda line: None)
    unknown = [v for v in variants if v not in VARIANTS]
    if unknown:
        raise openup_ompl.ConfigError("variants", unknown, f"some of {list(VARIANTS)}")
    problems, runs, plans = [], [], []
    files = find_problems(paths)
    total = len(files) * len(seeds) * len(variants)
    done = rounds = 0
    for path in files:
        say(f"preparing {problem_id(path)}")
        peers = prepare(path, resolution, planner_range)
        problems.append(peers)
        for seed in seeds:
            shift = rounds % len(variants)
            rounds += 1
            for variant in [*variants[shift:], *variants[:shift]]:
                done += 1
                target = peers.setup if variant in OURS else peers.fixed
                if isinstance(target, str):
                    record: dict[str, Any] = {"solved": False, "infeasible": target}
                elif variant in OURS:
                    record, plan = run_ours(target, variant, seed, time_limit)
                    if plan is not None:
                        plans.append(plan)
                elif variant == "pyroboplan":
                    record = run_pyroboplan(peers, seed, time_limit, peer_range)
                else:
                    record = run_reference(peers, time_limit)
                record.update(problem=peers.name, variant=variant, seed=seed)
                runs.append(record)
                outcome = record.get("infeasible") or (
                    f"ok {record['time_s']:.3f} s" if record["solved"] else "FAILED"
                ) + (f" (wall {record['wall_s']:.3f} s)" if "wall_s" in record else "") + (
                    "" if record.get("valid", True) else ", fails our exact check"
                )
                say(f"[{done}/{total}] {peers.name} {variant:<14} seed {seed}: {outcome}")
    summary = summarize(problems, runs, variants)
    return {
        "problems": [p.name for p in problems],
        "steps_rad": {p.name: p.step for p in problems},
        "runs": runs,
        "summary": summary,
        "plans": plans,
    }


def _geomean(values: Sequence[float]) -> float:
    finite = [v for v in values if math.isfinite(v) and v > 0]
    return math.exp(sum(map(math.log, finite)) / len(finite)) if finite else math.nan


def summarize(
    problems: Sequence[Peers], runs: Sequence[dict[str, Any]], variants: Sequence[str]
) -> dict[str, Any]:
    """Per problem and variant: runs, solved, median time and wall; the ratios."""
    per_problem: dict[str, dict[str, Any]] = {}
    for peers in problems:
        cells: dict[str, Any] = {}
        for variant in variants:
            mine = [r for r in runs if r["problem"] == peers.name and r["variant"] == variant]
            feasible = [r for r in mine if "infeasible" not in r]
            valid = [r for r in feasible if r["solved"] and "valid" in r]
            cells[variant] = {
                "runs": len(mine),
                "feasible": bool(feasible),
                "solved": sum(r["solved"] for r in feasible),
                "median_s": _common.median([r["time_s"] for r in feasible]),
                "median_wall_s": _common.median([r["wall_s"] for r in feasible]),
                "valid": sum(r["valid"] for r in valid),
                "checked": len(valid),
            }
        peer = cells.get("pyroboplan", {}).get("median_s", math.nan)
        for ours in OURS:
            if ours in cells:
                cells[f"pyroboplan/{ours}"] = peer / cells[ours]["median_s"]
        per_problem[peers.name] = cells
    geomeans = {
        f"pyroboplan/{ours}": _geomean(
            [c.get(f"pyroboplan/{ours}", math.nan) for c in per_problem.values()]
        )
        for ours in OURS
    }
    all_ours_solved = all(
        cell[v]["solved"] == cell[v]["runs"]
        for cell in per_problem.values()
        for v in OURS
        if v in cell
    )
    ratio = geomeans["pyroboplan/ikbirrt"]
    peer_failures = sum(
        c["pyroboplan"]["runs"] - c["pyroboplan"]["solved"]
        for c in per_problem.values()
        if "pyroboplan" in c and c["pyroboplan"]["feasible"]
    )
    scene_ratios = {name: c.get("pyroboplan/ikbirrt", math.nan) for name, c in per_problem.items()}
    below = sorted(name for name, r in scene_ratios.items() if not r >= SCENE_TARGET)
    least = min(scene_ratios.items(), key=lambda item: item[1], default=(None, math.nan))
    return {
        "peer_failures": peer_failures,
        "per_problem": per_problem,
        "geomean": geomeans,
        "least_ratio": {"problem": least[0], "pyroboplan/ikbirrt": least[1]},
        "below_scene_target": below,
        "all_ours_solved": all_ours_solved,
        "target_met": bool(
            math.isfinite(ratio) and ratio >= TARGET and all_ours_solved and not below
        ),
    }


def _cell(cell: dict[str, Any]) -> str:
    if not cell["feasible"]:
        return "infeasible"
    return f"{cell['solved']}/{cell['runs']} · {cell['median_s']:.3f}"


def _ratio(value: float, bound: bool) -> str:
    if not math.isfinite(value):
        return "-"
    return f"{'≥ ' if bound else ''}{value:.1f}×"


def report(result: dict[str, Any], info: dict[str, Any], args: dict[str, Any]) -> str:
    """The Markdown tables of a :func:`run_peers` result."""
    summary = result["summary"]
    variants = args["variants"]
    header = ["problem"]
    names = {
        "ikbirrt": "ikbirrt",
        "rrtconnect": "rrtconnect",
        "pyroboplan": "pyroboplan (w, joint goal)",
        "ompl-reference": "OMPL ref (w, joint goal)",
    }
    for variant in variants:
        header.append(f"{names[variant]} solved · median s")
        if variant in OURS:
            header.append(f"{variant} wall s")
        if variant in ("pyroboplan", "ompl-reference"):
            header.append("paths pass ours")
    ratios = [
        f"pyroboplan / {ours}" for ours in OURS if ours in variants and "pyroboplan" in variants
    ]
    header += ratios
    rows = []
    for name, cells in summary["per_problem"].items():
        row: list[object] = [name]
        for variant in variants:
            cell = cells[variant]
            row.append(_cell(cell))
            if variant in OURS:
                row.append(f"{cell['median_wall_s']:.3f}" if cell["feasible"] else "-")
            if variant in ("pyroboplan", "ompl-reference"):
                row.append(f"{cell['valid']}/{cell['checked']}" if cell["checked"] else "-")
        peer_failed = (
            "pyroboplan" in cells and cells["pyroboplan"]["solved"] < cells["pyroboplan"]["runs"]
        )
        for ours in OURS:
            if f"pyroboplan / {ours}" in ratios:
                row.append(_ratio(cells[f"pyroboplan/{ours}"], peer_failed))
        rows.append(row)
    if ratios:
        rows.append(
            ["**geometric mean**", *[""] * (len(header) - 1 - len(ratios))]
            + [
                _ratio(summary["geomean"][f"pyroboplan/{o}"], summary["peer_failures"] > 0)
                for o in OURS
                if f"pyroboplan / {o}" in ratios
            ]
        )
    lines = [
        "## Peer comparison: pyroboplan RRT-Connect, ours, bare OMPL",
        "",
        _common.machine_line(info),
        "",
        f"{len(args['seeds'])} seeds per problem ({args['seeds'][0]}..{args['seeds'][-1]}), "
        f"time limit {args['time']:g} s for every planner, runs interleaved (order rotated), "
        f"OMPL RNG seed {args['ompl_seed']}, extension step {args['range']:g} rad (pyroboplan: "
        f"{args['peer_range']:g} rad, goal bias {PEER_GOAL_BIAS:g}, its example's). Ours: the "
        "hand law and the grasp pose as goal (IK sampled while planning); time = "
        "`plan.solve_time_s`, wall = the whole `solve()`. pyroboplan and the OMPL reference: "
        "hand frozen at `w`, one joint goal (the same IK solution), edges checked every "
        f"{_common.median(list(result['steps_rad'].values())):.4f} rad (≤ 6 mm of robot "
        "motion); time = wall time of `plan()` / `solve()`. A failed run counts as the time "
        "limit (ratios then marked ≥). Ratios: median / median per problem.",
        "",
        _common.markdown_table(header, rows),
        "",
    ]
    if ratios:
        mean = summary["geomean"]["pyroboplan/ikbirrt"]
        least = summary["least_ratio"]
        below = summary["below_scene_target"]
        under = f"under {SCENE_TARGET:g}×: " + (", ".join(below) if below else "none")
        least_cells = summary["per_problem"].get(least["problem"], {})
        least_failed = "pyroboplan" in least_cells and (
            least_cells["pyroboplan"]["solved"] < least_cells["pyroboplan"]["runs"]
        )
        lines.append(
            f"Target: pyroboplan / ikbirrt ≥ {SCENE_TARGET:g}× on every problem and "
            f"≥ {TARGET:g}× as geometric mean, with all of ours solved: "
            f"{'met' if summary['target_met'] else 'NOT met'} "
            f"(geometric mean {_ratio(mean, summary['peer_failures'] > 0)}; least "
            f"{_ratio(least['pyroboplan/ikbirrt'], least_failed)} on {least['problem']}; "
            f"{under}; "
            f"pyroboplan failed {summary['peer_failures']} run(s), "
            f"ours {'all' if summary['all_ours_solved'] else 'not all'} solved)."
        )
    else:
        lines.append("pyroboplan did not run: no ratios.")
    checked, passed = result["recheck"]
    lines.append(
        f"recheck: {passed}/{checked} plans pass (`tests/recheck.py` on every plan of ours)"
    )
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--problems",
        nargs="+",
        default=[str(default_problems_dir("panda"))],
        metavar="DIR|FILE",
        help="scene files or directories of them (default: the Panda suite)",
    )
    parser.add_argument("--seeds", type=int, default=3, help="seeds per problem (default 3)")
    parser.add_argument("--first-seed", type=int, default=1, help="first seed (default 1)")
    parser.add_argument("--time", type=float, default=10.0, help="seconds per run (default 10)")
    parser.add_argument(
        "--range",
        type=float,
        default=0.4,
        help="largest extension step of ours and the OMPL reference [rad] (default 0.4)",
    )
    parser.add_argument(
        "--peer-range",
        type=float,
        default=PEER_RANGE,
        help=f"pyroboplan's max_connection_dist [rad] (default {PEER_RANGE:g})",
    )
    parser.add_argument(
        "--variants",
        nargs="+",
        default=list(VARIANTS),
        choices=VARIANTS,
        help="what to run (default: all)",
    )
    parser.add_argument(
        "--ompl-seed", type=int, default=1, help="ompl.util.RNG.setSeed before any OMPL object"
    )
    parser.add_argument("--json", metavar="PATH", help="also write the results as JSON")
    args = parser.parse_args(argv)
    if args.seeds < 1 or not (args.time > 0 and args.range > 0 and args.peer_range > 0):
        parser.error("--seeds must be >= 1, --time, --range and --peer-range > 0")
    variants = [v for v in VARIANTS if v in args.variants]
    version = pyroboplan_version()
    if version is None and "pyroboplan" in variants:
        print(
            "bench_peers: pyroboplan is not installed, skipping it "
            "(pip install --no-deps pyroboplan==1.3.1; see benchmarks/README.md)",
            file=sys.stderr,
        )
        variants.remove("pyroboplan")

    ou.setLogLevel(ou.LOG_ERROR)
    ou.RNG.setSeed(args.ompl_seed)
    info = _common.machine_info()
    if "pyroboplan" in variants:
        info["versions"]["pyroboplan"] = version
    seeds = list(range(args.first_seed, args.first_seed + args.seeds))
    started = time.perf_counter()
    result = run_peers(
        args.problems,
        seeds,
        args.time,
        variants,
        args.range,
        args.peer_range,
        progress=lambda line: print(line, file=sys.stderr, flush=True),
    )
    result["recheck"] = _common.recheck_plans(result.pop("plans"))
    elapsed = time.perf_counter() - started
    options = {
        "seeds": seeds,
        "time": args.time,
        "range": args.range,
        "peer_range": args.peer_range,
        "ompl_seed": args.ompl_seed,
    }
    print(report(result, info, {**options, "variants": variants}))
    print(f"bench_peers: {elapsed:.0f} s", file=sys.stderr)
    _common.write_json(
        args.json,
        {
            "benchmark": "bench_peers",
            "machine": info,
            "args": {**options, "problems": args.problems, "variants": variants},
            **result,
            "elapsed_s": elapsed,
        },
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
