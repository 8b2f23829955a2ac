"""The price of coupling itself: the coupled state check against a fixed-hand check of the
same states on identical geometry, on every shipped robot.

Per robot (its demo scene), two checkers on one collision world: the planner's coupled
check (``CoupledChecker.is_valid``: arm state -> forward kinematics -> ``d`` -> the hand
law -> Coal) and the same class with the classical fixed preshape at the law's plateau
(``HandLaw.fixed``: the hand never moves, no ``d``), which is how the planner checks a
fixed hand. Beside them: each through OMPL (``si.isValid``), the bare fixed-hand floor (write
``q``, one ``pin.computeCollisions``: what any Python checker pays), the bare check of the
law's own configuration precomputed (identical geometry on every state), and the coupled
check in its other order (forward kinematics for ``d`` first, then the collision query,
which repeats them: the order it takes near the grasp).

Two sets of arm states per robot: uniform in the joint limits (what a planner samples;
almost all on the law's plateau, where the fixed hand is the law's hand) and near the
grasp (``d <= mga``, where the law moves the fingers: Gaussian steps around an IK
solution of the grasp). Every verdict of every check is compared with a history-free
reference, Pinocchio's pair loop with the world's margins and no GJK warm start; any
disagreement fails the script.

The states are cut into chunks (``--chunk``, 250); in each round every variant checks
every chunk, the variants of one chunk one after the other (order rotated from chunk to
chunk, GC off), timed in this thread's CPU time. Each (round, chunk) is a sample; the
tables give per variant the median time per check over samples and the median over
samples of its time over the fixed-hand check's of the same sample: ratios of checks run
side by side on the same states, on one (possibly busy) machine.

With ``--native`` the package's checks with the compiled path on (``native="on"``,
:mod:`openup_ompl.native`; built by ``openup-ompl build-native``) are timed beside them:
the coupled and fixed-hand checkers, direct and through OMPL, their ``/ fixed`` ratios
over the compiled fixed-hand check. The Python variants run with ``native="off"``.

Run (about 30 s on 2 idle cores; times are this thread's CPU time)::

    python benchmarks/bench_coupling.py
    openup-ompl build-native && python benchmarks/bench_coupling.py --native
    python benchmarks/bench_coupling.py --states 2000 --rounds 9 --json bench_coupling.json
"""

from __future__ import annotations

import argparse
import gc
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
from ompl import base as ob
from ompl import util as ou

sys.path.insert(0, str(Path(__file__).resolve().parent))

import _common  # noqa: E402

import openup_ompl  # noqa: E402
from openup_ompl._resources import data_dir  # noqa: E402
from openup_ompl.collision import _with_margins, _without_warm_start  # noqa: E402
from openup_ompl.ompl_setup import arm_state_space  # noqa: E402
from openup_ompl.validity import CoupledChecker, CoupledValidityChecker  # noqa: E402

#: Each robot's demo scene.
SCENES = {
    name: data_dir("scenes") / f"{name}_can.toml" for name in ("panda", "lwa3_sdh", "ur5_allegro")
}
#: The variants, in the tables' order: name -> label.
LABELS = {
    "coupled": "coupled (`checker.is_valid`)",
    "fixed": "fixed hand, same class (`HandLaw.fixed`)",
    "coupled via OMPL": "coupled via OMPL (`si.isValid`)",
    "fixed via OMPL": "fixed hand via OMPL (`si.isValid`)",
    "bare fixed": "bare fixed hand: write `q`, one `pin.computeCollisions`",
    "bare same q": "bare, the law's own `q` precomputed: write it, one `pin.computeCollisions`",
    "FK first": "coupled, forward kinematics first (the order near the grasp)",
    "compiled coupled": 'compiled coupled (`checker.is_valid`, `native="on"`)',
    "compiled fixed": 'compiled fixed hand (`checker.is_valid`, `native="on"`)',
    "compiled coupled via OMPL": "compiled coupled via OMPL (`si.isValid`)",
    "compiled fixed via OMPL": "compiled fixed hand via OMPL (`si.isValid`)",
}


def base_variant(name: str) -> str:
    """The fixed-hand check a variant's ``/ fixed`` ratio divides by: the same
    implementation's (Python or compiled), through OMPL for a coupled check through OMPL."""
    prefix = "compiled " if name.startswith("compiled ") else ""
    return prefix + ("fixed via OMPL" if name.endswith("coupled via OMPL") else "fixed")


def timed_rounds(
    chunks: list[dict[str, Callable[[], object]]], sizes: list[int], rounds: int
) -> dict[str, list[float]]:
    """CPU seconds of this thread per state, of each check on each chunk of states in each
    round after the first (a warm-up): one sample per (round, chunk), the checks of a
    chunk timed one after the other (their order rotated and reversed from sample to
    sample, GC off). Thread CPU time, not wall time: the time a busy machine's other
    processes take the core is not counted, and short samples are each less likely to
    meet a context switch."""
    names = list(chunks[0])
    times: dict[str, list[float]] = {name: [] for name in names}
    gc_was_enabled = gc.isenabled()
    gc.disable()
    try:
        sample = 0
        for r in range(rounds):
            for checks, size in zip(chunks, sizes, strict=True):
                k = sample % len(names)
                order = names[k:] + names[:k]
                for name in order[::-1] if sample % 2 else order:
                    started = time.thread_time()
                    checks[name]()
                    if r:
                        times[name].append((time.thread_time() - started) / size)
                sample += 1
    finally:
        if gc_was_enabled:
            gc.enable()
    return times


def paired_ratios(times: dict[str, list[float]]) -> dict[str, dict[str, float]]:
    """Per variant, the median over samples of its time over the fixed-hand check's
    (``/ fixed``; coupled via OMPL over fixed hand via OMPL) and over the bare check of the
    law's own configuration (``/ same q``), each sample's times side by side."""
    out = {}
    for name, values in times.items():
        base = times[base_variant(name)]
        same = times["bare same q"]
        out[name] = {
            "/ fixed": float(np.median(np.divide(values, base))),
            "/ same q": float(np.median(np.divide(values, same))),
        }
    return out


def near_grasp_states(
    checker: CoupledChecker, grasp_arm: np.ndarray, count: int, rng: np.random.Generator
) -> np.ndarray:
    """``count`` arm states with ``d <= mga`` around ``grasp_arm`` (Gaussian steps,
    clipped to the limits, the spread halved while too few land under ``mga``)."""
    robot, mga = checker.robot, checker.law.mga
    sigma, found, tries = 0.3, [], 0
    while len(found) < count:
        tries += 1
        if tries > 200 * count:
            raise SystemExit(f"{robot.name}: could not sample {count} states with d <= mga")
        arm = np.clip(
            grasp_arm + rng.normal(scale=sigma, size=grasp_arm.size),
            robot.arm_lower,
            robot.arm_upper,
        )
        if checker.normalized_distance(arm) <= mga:
            found.append(arm)
        elif tries % 50 == 0 and len(found) < tries // 100:
            sigma /= 2
    return np.array(found)


def reference_verdicts(checker: CoupledChecker, qs: list[np.ndarray]) -> list[bool]:
    """Free or not, from Pinocchio's pair loop on new data with the world's margins and
    no GJK warm start (so that no answer depends on the queries before it)."""
    world = checker.finest_world
    model, geometry_model = world.model, world.geometry_model
    data = model.createData()
    geometry_data = _with_margins(_without_warm_start(geometry_model.createData()), world.margins)
    collide = pin.computeCollisions
    return [not collide(model, data, geometry_model, geometry_data, q, True) for q in qs]


def ompl_info(robot: openup_ompl.Robot, checker: CoupledChecker) -> ob.SpaceInformation:
    si = ob.SpaceInformation(arm_state_space(robot))
    si.setStateValidityChecker(CoupledValidityChecker(si, checker))
    si.setup()
    return si


def compiled_variants(
    compiled: tuple[CoupledChecker, CoupledChecker], arms: np.ndarray
) -> dict[str, Callable[[], list[bool]]]:
    """The package's checks with the compiled path on (``native="on"``), coupled and
    fixed hand, direct and through OMPL, each returning its verdicts."""
    robot = compiled[0].robot
    lists = [arm.tolist() for arm in arms]
    checks: dict[str, Callable[[], list[bool]]] = {}
    for hand, checker in zip(("coupled", "fixed"), compiled, strict=True):
        si = ompl_info(robot, checker)
        states = []
        for arm in lists:
            state = si.allocState()
            state[0 : robot.arm_idx.size] = arm
            states.append(state)
        call = checker.is_valid
        checks[f"compiled {hand}"] = lambda call=call: [call(a) for a in lists]
        checks[f"compiled {hand} via OMPL"] = lambda si=si, states=states: [
            si.isValid(s) for s in states
        ]
    return checks


def variants(
    law_checker: CoupledChecker,
    fixed_checker: CoupledChecker,
    arms: np.ndarray,
    compiled: tuple[CoupledChecker, CoupledChecker] | None = None,
) -> tuple[dict[str, Callable[[], list[bool]]], dict[str, list[np.ndarray]]]:
    """The measured checks of ``arms`` (each returning its verdicts), and the full
    configurations each one checks (for the reference); the compiled checks too when
    ``compiled`` (coupled and fixed-hand checkers with ``native="on"``) is given."""
    robot = law_checker.robot
    dof = robot.arm_idx.size
    lists = [arm.tolist() for arm in arms]
    law_si, fixed_si = ompl_info(robot, law_checker), ompl_info(robot, fixed_checker)
    states = {}
    for name, si in (("law", law_si), ("fixed", fixed_si)):
        states[name] = []
        for arm in lists:
            state = si.allocState()
            state[0:dof] = arm
            states[name].append(state)
    world = law_checker.finest_world
    context = world.context()
    model, data, manager, q = world.model, context.data, context.manager, context.q
    arm_sel, hand_sel = law_checker._arm_sel, law_checker._hand_sel
    fixed_hand = fixed_checker.law.fixed_clipped
    collide = pin.computeCollisions

    def coupled() -> list[bool]:
        is_valid = law_checker.is_valid
        return [is_valid(a) for a in lists]

    def fixed() -> list[bool]:
        is_valid = fixed_checker.is_valid
        return [is_valid(a) for a in lists]

    def coupled_ompl() -> list[bool]:
        is_valid = law_si.isValid
        return [is_valid(s) for s in states["law"]]

    def fixed_ompl() -> list[bool]:
        is_valid = fixed_si.isValid
        return [is_valid(s) for s in states["fixed"]]

    def bare_fixed() -> list[bool]:
        out = []
        for a in lists:
            q[arm_sel] = a
            q[hand_sel] = fixed_hand
            out.append(not collide(model, data, manager, q, True))
        return out

    def bare_same_q() -> list[bool]:
        out = []
        for a, hand in zip(lists, law_hands, strict=True):
            q[arm_sel] = a
            q[hand_sel] = hand
            out.append(not collide(model, data, manager, q, True))
        return out

    def fk_first() -> list[bool]:
        fill = law_checker._fill
        out = []
        for a in lists:
            fill(context, a)
            out.append(not collide(model, data, manager, q, True))
        return out

    law_qs = [law_checker.coupled_q(arm) for arm in arms]
    law_hands = [qs[hand_sel] for qs in law_qs]
    fixed_qs = [fixed_checker.coupled_q(arm) for arm in arms]
    checks = {
        "coupled": coupled,
        "fixed": fixed,
        "coupled via OMPL": coupled_ompl,
        "fixed via OMPL": fixed_ompl,
        "bare fixed": bare_fixed,
        "bare same q": bare_same_q,
        "FK first": fk_first,
    }
    if compiled is not None:
        checks.update(compiled_variants(compiled, arms))
    configurations = {name: fixed_qs if "fixed" in name else law_qs for name in checks}
    return checks, configurations


def bench_robot(robot_name: str, args: argparse.Namespace) -> dict[str, Any]:
    problem = openup_ompl.load_scene(SCENES[robot_name])
    setup = openup_ompl.GraspPlanningSetup(problem, native="off")
    law_checker = setup.checker
    law = law_checker.law
    fixed_law = law.with_options(fixed=law.high)
    fixed_checker = CoupledChecker(
        problem, fixed_law, resolution=law_checker.resolution, native="off"
    )
    compiled = None
    if args.native:
        compiled = tuple(
            CoupledChecker(problem, each, resolution=law_checker.resolution, native="on")
            for each in (law, fixed_law)
        )
    law_world, fixed_world = law_checker.finest_world, fixed_checker.finest_world
    assert law_world.padding == fixed_world.padding
    assert np.array_equal(law_world.margins, fixed_world.margins)
    assert law_world.geometry_model.ngeoms == fixed_world.geometry_model.ngeoms

    rng = np.random.default_rng(args.seed)
    robot = problem.robot
    sets = {
        "uniform": rng.uniform(robot.arm_lower, robot.arm_upper, (args.states, robot.arm_idx.size)),
        "near the grasp": near_grasp_states(
            law_checker, setup.goal.ensure_solution(), args.states, rng
        ),
    }
    out: dict[str, Any] = {"scene": str(SCENES[robot_name]), "sets": {}}
    for set_name, arms in sets.items():
        chunks = [arms[k : k + args.chunk] for k in range(0, len(arms), args.chunk)]
        checks = []
        valid = hands_differ = 0
        for chunk in chunks:
            chunk_checks, configurations = variants(law_checker, fixed_checker, chunk, compiled)
            checkers = [law_checker, fixed_checker, *(compiled or ())]
            valid += sum(verify(checkers, chunk_checks, configurations))
            hands_differ += sum(
                not np.array_equal(a, b)
                for a, b in zip(configurations["coupled"], configurations["fixed"], strict=True)
            )
            checks.append(chunk_checks)
        distances = np.array([law_checker.normalized_distance(arm) for arm in arms])
        times = timed_rounds(checks, [len(c) for c in chunks], args.rounds)
        out["sets"][set_name] = {
            "states": len(arms),
            "samples": len(times["coupled"]),
            "valid_fraction": valid / len(arms),
            "on_plateau_fraction": float(np.mean(distances > law.mga)),
            "hands_differ": int(hands_differ),
            "median_s_per_state": {name: _common.median(v) for name, v in times.items()},
            "ratios": paired_ratios(times),
        }
    return out


def verify(
    checkers: list[CoupledChecker],
    checks: dict[str, Callable[[], list[bool]]],
    configurations: dict[str, list[np.ndarray]],
) -> list[bool]:
    """Run every check once and compare its verdicts with the reference's (exit on a
    difference); return the coupled configurations' reference verdicts. ``checkers``:
    the coupled checker first, then the others (forgotten before each check)."""
    law_checker = checkers[0]
    references = {id(qs): reference_verdicts(law_checker, qs) for qs in configurations.values()}
    for name, check in checks.items():
        for checker in checkers:
            checker.forget()
        got = check()
        expected = references[id(configurations[name])]
        wrong = [i for i, (a, b) in enumerate(zip(got, expected, strict=True)) if a != b]
        if wrong:
            raise SystemExit(
                f"{law_checker.robot.name}: {name} disagrees with the reference on "
                f"{len(wrong)} states (first: {wrong[:5]})"
            )
    return references[id(configurations["coupled"])]


def report(info: dict[str, Any], results: dict[str, Any], args: argparse.Namespace) -> str:
    out = [
        "## The price of coupling: coupled vs fixed-hand state checks, identical geometry",
        "",
        _common.machine_line(info),
        "",
        f"µs of thread CPU time per check: the median over samples ({args.rounds - 1} "
        f"interleaved rounds after a warm-up, each over chunks of {args.chunk} states; every "
        "variant timed on the same chunk in each sample). / fixed: the median over samples of "
        "the variant's time over the fixed-hand check's (same class, direct call; coupled "
        "via OMPL over fixed hand via OMPL). / same q: the same over the bare check of the "
        "law's own configuration (identical geometry on every state). Every verdict equal "
        "to a history-free pair-loop reference.",
        "",
    ]
    header = ["robot", "states", "variant", "µs/check", "/ fixed", "/ same q"]
    rows = []
    for robot_name, entry in results.items():
        for set_name, s in entry["sets"].items():
            med, ratios = s["median_s_per_state"], s["ratios"]
            for key, label in LABELS.items():
                if key not in med:
                    continue
                rows.append(
                    [
                        robot_name,
                        set_name,
                        label,
                        f"{1e6 * med[key]:.2f}",
                        f"{ratios[key]['/ fixed']:.3f}",
                        f"{ratios[key]['/ same q']:.3f}",
                    ]
                )
    out.append(_common.markdown_table(header, rows, left=3))
    out += ["", "State sets:", ""]
    for robot_name, entry in results.items():
        for set_name, s in entry["sets"].items():
            out.append(
                f"- {robot_name}, {set_name}: {s['states']} states ({s['samples']} samples), "
                f"{100 * s['valid_fraction']:.1f} % collision-free, "
                f"{100 * s['on_plateau_fraction']:.1f} % on the law's plateau (d > mga), "
                f"the fixed hand differs from the law's in {s['hands_differ']}."
            )
    return "\n".join(out)


def add_common_arguments(parser: argparse.ArgumentParser) -> None:
    """The options this script and ``bench_native.py`` share: robots, state sets, rounds."""
    parser.add_argument(
        "--robots", nargs="+", default=list(SCENES), choices=list(SCENES), help="robots"
    )
    parser.add_argument("--states", type=int, default=2000, help="states per set (2000)")
    parser.add_argument("--rounds", type=int, default=9, help="interleaved rounds (9)")
    parser.add_argument("--chunk", type=int, default=250, help="states per sample (250)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the states")
    parser.add_argument("--json", metavar="PATH", help="also write the results as JSON")


def run(
    name: str,
    parser: argparse.ArgumentParser,
    bench: Callable[[str, argparse.Namespace], dict[str, Any]],
    describe: Callable[[dict[str, Any], dict[str, Any], argparse.Namespace], str],
    note: str,
) -> None:
    """Parse the options, bench each robot, print the report, write the JSON.

    Args:
        name: The benchmark's name (in the JSON).
        parser: The parser, every option added.
        bench: Runs one robot: ``bench(robot_name, args)`` -> its results.
        describe: The report: ``describe(machine, results, args)`` -> Markdown.
        note: What the JSON's times and ratios are.
    """
    args = parser.parse_args()
    if args.states < 1 or args.chunk < 1 or args.rounds < 2:
        parser.error("--states and --chunk must be positive, --rounds at least 2")
    ou.setLogLevel(ou.LOG_ERROR)
    info = _common.machine_info()
    results = {}
    for robot_name in args.robots:
        started = time.perf_counter()
        results[robot_name] = bench(robot_name, args)
        print(f"{robot_name}: {time.perf_counter() - started:.1f} s", file=sys.stderr)
    print(describe(info, results, args))
    _common.write_json(
        args.json,
        {
            "benchmark": name,
            "machine": info,
            "args": {k: v for k, v in vars(args).items() if k != "json"},
            "robots": results,
            "note": note,
        },
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_common_arguments(parser)
    parser.add_argument(
        "--native",
        action="store_true",
        help="also time the package's checks with the compiled path on (native='on'; "
        "build it first: openup-ompl build-native)",
    )
    run("bench_coupling", parser, bench_robot, report,
        "times in seconds per check; ratios are of medians over interleaved rounds")  # fmt: skip


if __name__ == "__main__":
    main()
