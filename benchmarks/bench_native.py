"""The coupled check compiled: whether C++ removes the price of coupling near the grasp.

The compiled module of :mod:`openup_ompl.native` (``coupled_check.cpp``, built by
``openup-ompl build-native``), called here directly, does the whole single-state check of
``StateChecker.is_valid`` at the finest margin in one call: the arm joints' placements,
the palm frame, ``d``, the law's hand, the hand joints' placements (forward kinematics
once), the geometry placements and Coal's naive broadphase query, on the same Pinocchio
data and manager as the Python check. Per robot (its demo scene) and state set (uniform
in the joint limits, and near the grasp, ``d <= mga``, as ``bench_coupling.py`` builds
them), four checks side by side: the Python coupled and fixed-hand checks
(``CoupledChecker.is_valid``, the fixed hand at the law's plateau) and the compiled
coupled and fixed-hand checks; each also through OMPL (``si.isValid``, the compiled one
behind a minimal ``StateValidityChecker`` that counts the state). Beside them, the bare
query of the law's own configuration precomputed, from Python and compiled: near the
grasp the law's hand differs from the fixed one, and so does the query's work; the
coupled check over the bare query of the same configuration is the law's own price on
identical geometry. Every verdict is
compared with a history-free pair-loop reference, and the compiled check's ``d`` with
the Python check's (bit for bit); any difference fails the script.

Timing as in ``bench_coupling.py``: chunks of ``--chunk`` states, every variant on every
chunk in each round after a warm-up, the order rotated, thread CPU time; medians over the
(round, chunk) samples, ratios the median over samples of the ratio of two variants timed
on the same chunk.

Run (about 40 s on 2 idle cores, after building the extension)::

    openup-ompl build-native
    python benchmarks/bench_native.py
    python benchmarks/bench_native.py --states 2000 --rounds 9 --json bench_native.json
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
from ompl import base as ob

sys.path.insert(0, str(Path(__file__).resolve().parent))

import _common  # noqa: E402
import bench_coupling  # noqa: E402

import openup_ompl  # noqa: E402
from openup_ompl import native  # noqa: E402
from openup_ompl.hand_law import DISTANCE_KINDS  # noqa: E402
from openup_ompl.ompl_setup import arm_state_space  # noqa: E402
from openup_ompl.validity import CoupledChecker  # noqa: E402

#: The variants: name -> (implementation, hand, through OMPL).
VARIANTS = {
    "python coupled": ("python", "coupled", False),
    "python fixed": ("python", "fixed", False),
    "native coupled": ("native", "coupled", False),
    "native fixed": ("native", "fixed", False),
    "python same q": ("python", "same q", False),
    "native same q": ("native", "same q", False),
    "python coupled via OMPL": ("python", "coupled", True),
    "python fixed via OMPL": ("python", "fixed", True),
    "native coupled via OMPL": ("native", "coupled", True),
    "native fixed via OMPL": ("native", "fixed", True),
}


class NativeValidityChecker(ob.StateValidityChecker):
    """OMPL state validity checker on the compiled check (as ``CoupledValidityChecker``
    would call it if wired in: the arm read from the state, the state counted)."""

    def __init__(self, si: ob.SpaceInformation, checker: CoupledChecker, native: Any) -> None:
        super().__init__(si)
        self.checker = checker
        self._native = native.is_valid
        self._n = checker.robot.arm_idx.size

    def isValid(self, state: ob.State) -> bool:  # noqa: N802 - OMPL's name
        self.checker.states_checked += 1
        return self._native(state[0 : self._n])  # type: ignore[no-any-return]


def native_info(checker: CoupledChecker, native: Any) -> ob.SpaceInformation:
    si = ob.SpaceInformation(arm_state_space(checker.robot))
    si.setStateValidityChecker(NativeValidityChecker(si, checker, native))
    si.setup()
    return si


def variants(
    checkers: dict[str, CoupledChecker], natives: dict[str, Any], arms: np.ndarray
) -> dict[str, Callable[[], list[bool]]]:
    """The measured checks of ``arms``, each returning its verdicts."""
    dof = checkers["coupled"].robot.arm_idx.size
    lists = [arm.tolist() for arm in arms]
    checks: dict[str, Callable[[], list[bool]]] = {}
    law_qs = [checkers["coupled"].coupled_q(arm) for arm in arms]
    context = checkers["coupled"].finest_world.context()
    model, data, manager = checkers["coupled"].finest_world.model, context.data, context.manager
    collide = pin.computeCollisions
    checks["python same q"] = lambda: [not collide(model, data, manager, q, True) for q in law_qs]
    q_lists = [q.tolist() for q in law_qs]
    native_q = natives["coupled"].is_valid_q
    checks["native same q"] = lambda: [native_q(q) for q in q_lists]
    for name, (implementation, hand, via_ompl) in VARIANTS.items():
        if hand == "same q":
            continue
        if not via_ompl:
            call = (checkers[hand] if implementation == "python" else natives[hand]).is_valid
            checks[name] = lambda call=call: [call(a) for a in lists]
            continue
        if implementation == "python":
            si = bench_coupling.ompl_info(checkers[hand].robot, checkers[hand])
        else:
            si = native_info(checkers[hand], natives[hand])
        states = []
        for arm in lists:
            state = si.allocState()
            state[0:dof] = arm
            states.append(state)
        call = si.isValid
        checks[name] = lambda call=call, states=states, si=si: [call(s) for s in states]
    return checks


def verify(
    checkers: dict[str, CoupledChecker],
    natives: dict[str, Any],
    checks: dict[str, Callable[[], list[bool]]],
    arms: np.ndarray,
) -> tuple[int, int, float]:
    """Run every check once, compare its verdicts with the reference's and the compiled
    ``d`` with the Python check's (exit on a difference); return the coupled
    configurations' collision-free count, the states whose compiled ``d`` equals the
    Python one bit for bit (all of them, or exit, with the translation distance; the
    weighted one's rotation goes through numpy's matrix product in Python) and the largest
    relative difference."""
    law_checker = checkers["coupled"]
    references = {
        hand: bench_coupling.reference_verdicts(
            law_checker, [checkers[hand].coupled_q(arm) for arm in arms]
        )
        for hand in ("coupled", "fixed")
    }
    name_of = law_checker.robot.name
    for name, check in checks.items():
        for checker in checkers.values():
            checker.forget()
        hand = VARIANTS[name][1]
        got, expected = check(), references["fixed" if hand == "fixed" else "coupled"]
        wrong = [i for i, (a, b) in enumerate(zip(got, expected, strict=True)) if a != b]
        if wrong:
            raise SystemExit(f"{name_of}: {name} disagrees with the reference on {wrong[:5]}")
    native = natives["coupled"]
    exact = law_checker.law.distance == "translation"
    equal, deviation = 0, 0.0
    for k, arm in enumerate(arms.tolist()):
        native.is_valid(arm)
        expected_d = law_checker._check_state(arm)[1]
        if native.distance == expected_d:
            equal += 1
        elif exact:
            raise SystemExit(
                f"{name_of}: state {k}: compiled d {native.distance!r} != Python {expected_d!r}"
            )
        deviation = max(deviation, abs(native.distance - expected_d) / expected_d)
    return sum(references["coupled"]), equal, deviation


def bench_robot(robot_name: str, args: argparse.Namespace) -> dict[str, Any]:
    problem = openup_ompl.load_scene(bench_coupling.SCENES[robot_name])
    setup = openup_ompl.GraspPlanningSetup(problem, native="off")
    law_checker = setup.checker
    law = law_checker.law
    if law.distance != args.distance:
        law = law.with_options(distance=args.distance)
        law_checker = CoupledChecker(problem, law, resolution=law_checker.resolution, native="off")
    fixed_checker = CoupledChecker(
        problem, law.with_options(fixed=law.high), resolution=law_checker.resolution, native="off"
    )
    checkers = {"coupled": law_checker, "fixed": fixed_checker}
    module = native.load()
    natives = {
        hand: native.compiled_check(module, checker, checker.finest_world)
        for hand, checker in checkers.items()
    }
    rng = np.random.default_rng(args.seed)
    robot = problem.robot
    sets = {
        "uniform": rng.uniform(robot.arm_lower, robot.arm_upper, (args.states, robot.arm_idx.size)),
        "near the grasp": bench_coupling.near_grasp_states(
            law_checker, setup.goal.ensure_solution(), args.states, rng
        ),
    }
    out: dict[str, Any] = {"scene": str(bench_coupling.SCENES[robot_name]), "sets": {}}
    for set_name, arms in sets.items():
        chunks = [arms[k : k + args.chunk] for k in range(0, len(arms), args.chunk)]
        checks, valid, d_equal, d_deviation = [], 0, 0, 0.0
        for chunk in chunks:
            chunk_checks = variants(checkers, natives, chunk)
            free, equal, deviation = verify(checkers, natives, chunk_checks, chunk)
            valid, d_equal = valid + free, d_equal + equal
            d_deviation = max(d_deviation, deviation)
            checks.append(chunk_checks)
        times = bench_coupling.timed_rounds(checks, [len(c) for c in chunks], args.rounds)
        out["sets"][set_name] = {
            "states": len(arms),
            "samples": len(times["python coupled"]),
            "valid_fraction": valid / len(arms),
            "d_equal": d_equal,
            "d_max_relative_difference": d_deviation,
            "median_s_per_state": {name: _common.median(v) for name, v in times.items()},
            "ratios": ratios(times),
        }
    return out


def ratios(times: dict[str, list[float]]) -> dict[str, float]:
    """Medians over samples of paired ratios: coupled / fixed per implementation (direct
    and through OMPL), and Python / compiled per hand."""

    def paired(a: str, b: str) -> float:
        return float(np.median(np.divide(times[a], times[b])))

    out = {}
    for via in ("", " via OMPL"):
        for implementation in ("python", "native"):
            out[f"{implementation} coupled/fixed{via}"] = paired(
                f"{implementation} coupled{via}", f"{implementation} fixed{via}"
            )
        for hand in ("coupled", "fixed"):
            out[f"python/native {hand}{via}"] = paired(f"python {hand}{via}", f"native {hand}{via}")
    for implementation in ("python", "native"):
        out[f"{implementation} coupled/same q"] = paired(
            f"{implementation} coupled", f"{implementation} same q"
        )
    return out


def report(info: dict[str, Any], results: dict[str, Any], args: argparse.Namespace) -> str:
    out = [
        "## The coupled check compiled: Python against C++, coupled against fixed hand",
        "",
        _common.machine_line(info),
        "",
        f"µs of thread CPU time per check, the median over samples ({args.rounds - 1} "
        f"interleaved rounds after a warm-up, chunks of {args.chunk} states). c/f: the "
        "median over samples of the coupled check's time over the fixed hand's (same "
        "implementation, same chunk); py/C++: Python's time over the compiled one's. Every "
        "verdict equal to a history-free pair-loop reference; the compiled d against the "
        f"Python check's below (the law's distance: {args.distance}).",
        "",
    ]
    for via in ("", " via OMPL"):
        header = [
            "robot",
            "states",
            "py coupled",
            "py fixed",
            "C++ coupled",
            "C++ fixed",
            "py c/f",
            "C++ c/f",
            "py/C++ coupled",
            "py/C++ fixed",
        ]
        rows = []
        for robot_name, entry in results.items():
            for set_name, s in entry["sets"].items():
                med, r = s["median_s_per_state"], s["ratios"]
                rows.append(
                    [
                        robot_name,
                        set_name,
                        *(
                            f"{1e6 * med[f'{i} {h}{via}']:.2f}"
                            for i in ("python", "native")
                            for h in ("coupled", "fixed")
                        ),
                        f"{r[f'python coupled/fixed{via}']:.3f}",
                        f"{r[f'native coupled/fixed{via}']:.3f}",
                        f"{r[f'python/native coupled{via}']:.2f}",
                        f"{r[f'python/native fixed{via}']:.2f}",
                    ]
                )
        title = "Through OMPL (`si.isValid`)" if via else "Direct calls (`is_valid(arm)`)"
        out += [f"{title}:", "", _common.markdown_table(header, rows, left=2), ""]
    header = ["robot", "states", "py same q", "C++ same q", "py c/same q", "C++ c/same q"]
    rows = []
    for robot_name, entry in results.items():
        for set_name, s in entry["sets"].items():
            med, r = s["median_s_per_state"], s["ratios"]
            rows.append(
                [
                    robot_name,
                    set_name,
                    f"{1e6 * med['python same q']:.2f}",
                    f"{1e6 * med['native same q']:.2f}",
                    f"{r['python coupled/same q']:.3f}",
                    f"{r['native coupled/same q']:.3f}",
                ]
            )
    out += [
        "The bare query of the law's own configuration, precomputed (identical geometry on "
        "every state; Python: one `pin.computeCollisions` of a full `q` array; C++: "
        "`is_valid_q` of the `nq` floats), and the coupled check's time over it (c/same q):",
        "",
        _common.markdown_table(header, rows, left=2),
        "",
    ]
    out.append("State sets:")
    out.append("")
    for robot_name, entry in results.items():
        for set_name, s in entry["sets"].items():
            out.append(
                f"- {robot_name}, {set_name}: {s['states']} states ({s['samples']} samples), "
                f"{100 * s['valid_fraction']:.1f} % collision-free, the compiled d equal to "
                f"the Python one in {s['d_equal']} (largest relative difference "
                f"{s['d_max_relative_difference']:.1g})."
            )
    return "\n".join(out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    bench_coupling.add_common_arguments(parser)
    parser.add_argument(
        "--distance",
        default="translation",
        choices=DISTANCE_KINDS,
        help="the law's distance (translation, the scenes' own)",
    )
    note = "times in seconds per check; ratios are medians of paired ratios"
    bench_coupling.run("bench_native", parser, bench_robot, report, note)


if __name__ == "__main__":
    main()
