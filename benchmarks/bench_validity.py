"""Cost of the coupled validity check and of the batched motion check, as ratios.

Part A (states): the OMPL ``CoupledValidityChecker`` called through OMPL
(``si.isValid(state)``: arm state -> FK -> hand law -> Coal) against bare Pinocchio + Coal
checks of exactly the same full configurations: the broadphase manager type the world
uses (naive), the dynamic AABB tree, Pinocchio's pair loop, and a "bare OMPL checker" (a
minimal Python ``ob.StateValidityChecker`` with a fixed hand, also called through OMPL:
what any Python OMPL checker costs without the law). The coupled cost is also split into
the fill (FK + law) and the collision query. Every verdict is checked against Pinocchio's
pair loop with Coal's GJK warm start off (history-free); a variant may differ from it
only where a fresh instance of the same check agrees with it (a warm-start artifact,
reported), anything else is an assertion error.

Part B (motions): ``CoupledChecker.check_motion`` (goal state, then the intermediate
states in one batched parallel query) against the same check on a one-thread world (one state at a
time) on random motions between valid configurations, at two lengths. Both must give the
same verdicts. States are counted from ``checker.states_checked`` deltas: the batch
counts every state it submits, even when the parallel query stops at a collision.

Every measured variant runs in each of several interleaved rounds (order rotated per
round, GC off); the tables give medians over rounds, so ratios come from one process run
on one (possibly noisy) machine.

Run (about 25 s on 2 idle cores; about 45 s when another process keeps a core busy,
as the 2-thread batches then stall)::

    python benchmarks/bench_validity.py
    python benchmarks/bench_validity.py --states 5000 --rounds 11 --motions 300 \
        --motion-rounds 5 --lengths 0.3 1.0 --json bench_validity.json
"""

from __future__ import annotations

import argparse
import gc
import sys
import time
import warnings
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
from openup_ompl.collision import CollisionWorld  # noqa: E402


class BareChecker(ob.StateValidityChecker):
    """The minimal Python OMPL checker: state -> q (fixed hand) -> naive-manager query."""

    def __init__(
        self,
        si: ob.SpaceInformation,
        model: pin.Model,
        geometry_model: pin.GeometryModel,
        q: np.ndarray,
        n: int,
    ) -> None:
        super().__init__(si)
        self._model = model
        self._data = model.createData()
        self._geometry_data = geometry_model.createData()
        self._manager = pin.BroadPhaseManager_NaiveCollisionManager(
            model, geometry_model, self._geometry_data
        )
        self._q = q.copy()
        self._n = n

    def isValid(self, state: ob.State) -> bool:  # noqa: N802 - OMPL's name
        q = self._q
        q[0 : self._n] = state[0 : self._n]
        return not pin.computeCollisions(self._model, self._data, self._manager, q, True)


def timed_rounds(
    variants: dict[str, Callable[[], object]], rounds: int, count: int
) -> dict[str, list[float]]:
    """Per-item seconds of each variant in each round (order rotated every round)."""
    names = list(variants)
    times: dict[str, list[float]] = {name: [] for name in names}
    gc_was_enabled = gc.isenabled()
    gc.disable()
    try:
        for r in range(rounds):
            order = names[r % len(names) :] + names[: r % len(names)]
            if r % 2:
                order.reverse()
            for name in order:
                started = time.perf_counter()
                variants[name]()
                times[name].append((time.perf_counter() - started) / count)
    finally:
        if gc_was_enabled:
            gc.enable()
    return times


def bench_states(setup: openup_ompl.GraspPlanningSetup, args: argparse.Namespace) -> dict:
    problem = setup.problem
    robot = problem.robot
    checker = setup.checker
    # Single states are checked against the finest margin (the coarser margins only serve
    # motion checks): the bare variants use that same geometry.
    world = checker.finest_world
    si = setup.space_information
    model = world.model
    geometry_model = world.geometry_model
    dof = robot.arm_idx.size
    if not np.array_equal(robot.arm_idx, np.arange(dof)):
        raise SystemExit("this benchmark assumes the arm joints come first in q")

    rng = np.random.default_rng(args.seed)
    arms = rng.uniform(robot.arm_lower, robot.arm_upper, size=(args.states, dof))
    arm_lists = [arm.tolist() for arm in arms]
    states = []
    for arm in arm_lists:
        state = si.allocState()
        state[0:dof] = arm
        states.append(state)
    qs = [checker.coupled_q(arm) for arm in arms]

    # The bare OMPL checker: a fixed hand (the law's plateau, what the law gives at most
    # random configurations), on its own SpaceInformation over the same state space.
    fixed_hand = setup.law.high
    q_fixed_template = robot.neutral()
    q_fixed_template[robot.hand_idx] = fixed_hand
    qs_fixed = []
    for arm in arms:
        q = q_fixed_template.copy()
        q[robot.arm_idx] = arm
        qs_fixed.append(q)
    bare_si = ob.SpaceInformation(setup.space)
    bare_checker = BareChecker(bare_si, model, geometry_model, q_fixed_template, dof)
    bare_si.setStateValidityChecker(bare_checker)
    bare_si.setup()

    def fresh(kind: type | None, warm_start: bool = True) -> tuple[pin.Data, Any, Any]:
        """New Pinocchio data, geometry data and manager (``None``: the pair loop)."""
        geometry_data = geometry_model.createData()
        if not warm_start:
            with warnings.catch_warnings():  # Coal deprecates the flag Pinocchio sets
                warnings.simplefilter("ignore", DeprecationWarning)
                for request in geometry_data.collisionRequests:
                    request.enable_cached_gjk_guess = False
        manager = None if kind is None else kind(model, geometry_model, geometry_data)
        return model.createData(), geometry_data, manager

    naive_kind = pin.BroadPhaseManager_NaiveCollisionManager
    tree_kind = pin.BroadPhaseManager_DynamicAABBTreeCollisionManager
    naive_data, _naive_gd, naive = fresh(naive_kind)
    cold_data, _cold_gd, cold_naive = fresh(naive_kind, warm_start=False)
    tree_data, _tree_gd, tree = fresh(tree_kind)
    pair_data, pair_geometry_data, _ = fresh(None)
    context = world.context()
    collide = pin.computeCollisions

    def coupled_ompl() -> list[bool]:
        is_valid = si.isValid
        return [is_valid(s) for s in states]

    def coupled_direct() -> list[bool]:
        is_valid = checker.is_valid
        return [is_valid(a) for a in arm_lists]

    def bare_ompl() -> list[bool]:
        is_valid = bare_si.isValid
        return [is_valid(s) for s in states]

    def bare_naive() -> list[bool]:
        return [not collide(model, naive_data, naive, q, True) for q in qs]

    def bare_naive_cold() -> list[bool]:
        return [not collide(model, cold_data, cold_naive, q, True) for q in qs]

    def bare_tree() -> list[bool]:
        return [not collide(model, tree_data, tree, q, True) for q in qs]

    def bare_pairs() -> list[bool]:
        return [
            not collide(model, pair_data, geometry_model, pair_geometry_data, q, True) for q in qs
        ]

    def fill() -> None:
        fill_ = checker._fill
        for a in arm_lists:
            fill_(context, a)

    def collision() -> list[bool]:
        manager, data = context.manager, context.data
        return [not collide(model, data, manager, q, True) for q in qs]

    def state_read() -> None:
        for s in states:
            s[0:dof]

    def empty_loop() -> list[bool]:
        return [True for _ in states]

    # Verdicts. The reference is Pinocchio's pair loop with Coal's GJK warm start off
    # (Pinocchio turns it on by default: ``enable_cached_gjk_guess``), whose verdicts do
    # not depend on the queries run before. A variant may differ from it only where a
    # fresh instance of the same check (no history) agrees with the reference: those
    # are GJK warm-start artifacts, counted and reported; anything else fails.
    def cold_verdicts(configurations: list[np.ndarray]) -> list[bool]:
        data, geometry_data, _ = fresh(None, warm_start=False)
        return [
            not collide(model, data, geometry_model, geometry_data, q, True) for q in configurations
        ]

    reference = cold_verdicts(qs)
    reference_fixed = cold_verdicts(qs_fixed)
    checks = {  # name -> (verdicts, manager kind used, configurations, reference)
        "coupled via OMPL": (coupled_ompl(), naive_kind, qs, reference),
        "coupled, direct": (coupled_direct(), naive_kind, qs, reference),
        "bare OMPL checker": (bare_ompl(), naive_kind, qs_fixed, reference_fixed),
        "bare naive": (bare_naive(), naive_kind, qs, reference),
        "bare naive, cold": (bare_naive_cold(), naive_kind, qs, reference),
        "bare tree": (bare_tree(), tree_kind, qs, reference),
        "bare pairs": (bare_pairs(), None, qs, reference),
        "collision": (collision(), naive_kind, qs, reference),
    }
    artifacts: dict[str, list[dict[str, Any]]] = {}
    for name, (got, kind, configurations, expected) in checks.items():
        for i, (a, b) in enumerate(zip(got, expected, strict=True)):
            if a == b:
                continue
            data, _geometry_data, manager = fresh(kind)
            if kind is None:
                again = not collide(
                    model, data, geometry_model, _geometry_data, configurations[i], True
                )
            else:
                again = not collide(model, data, manager, configurations[i], True)
            assert again == b, f"{name}: state {i} valid={a}, cold reference valid={b}"
            artifacts.setdefault(name, []).append({"state": i, "valid": a, "cold_valid": b})
    hand_changes = sum(a != b for a, b in zip(reference, reference_fixed, strict=True))

    variants = {
        "coupled via OMPL": coupled_ompl,
        "coupled, direct": coupled_direct,
        "bare OMPL checker": bare_ompl,
        "bare naive": bare_naive,
        "bare naive, cold": bare_naive_cold,
        "bare tree": bare_tree,
        "bare pairs": bare_pairs,
        "fill": fill,
        "collision": collision,
        "state read": state_read,
        "empty loop": empty_loop,
    }
    for run in variants.values():  # warm-up
        run()
    times = timed_rounds(variants, args.rounds, len(states))
    med = {name: _common.median(values) for name, values in times.items()}
    return {
        "states": len(states),
        "valid_fraction": sum(reference) / len(reference),
        "fixed_hand": fixed_hand.tolist(),
        "fixed_vs_law_verdicts_differ": hand_changes,
        "warm_start_artifacts": artifacts,
        "rounds": args.rounds,
        "median_s_per_state": med,
        "min_s_per_state": {name: min(values) for name, values in times.items()},
        "max_s_per_state": {name: max(values) for name, values in times.items()},
    }


def sample_motions(
    checker: openup_ompl.CoupledChecker,
    lower: np.ndarray,
    upper: np.ndarray,
    length: float,
    count: int,
    rng: np.random.Generator,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """``count`` straight motions of exactly ``length`` [rad] between valid configurations."""
    motions: list[tuple[np.ndarray, np.ndarray]] = []
    tries = 0
    while len(motions) < count:
        tries += 1
        if tries > 10_000 * count:
            raise SystemExit(f"could not sample {count} valid motions of length {length}")
        a = rng.uniform(lower, upper)
        if not checker.is_valid(a):
            continue
        for _ in range(20):
            direction = rng.normal(size=a.size)
            b = a + length * direction / np.linalg.norm(direction)
            if np.all(b >= lower) and np.all(b <= upper) and checker.is_valid(b):
                motions.append((a, b))
                break
    return motions


def bench_motions(setup: openup_ompl.GraspPlanningSetup, args: argparse.Namespace) -> list[dict]:
    checker = setup.checker
    problem = setup.problem
    robot = problem.robot
    # The same check on a world whose batches run on one thread: separates what batching
    # costs from what the parallel threads bring (or cost, on a loaded machine).
    # Same geometry as the setup's world (its obstacle padding, when the package has one).
    padding = getattr(checker.world, "padding", None)
    world_options = {} if padding is None else {"padding": padding}
    checker_1 = openup_ompl.CoupledChecker(
        problem,
        setup.law,
        world=CollisionWorld(problem, num_threads=1, **world_options),
        resolution=checker.resolution,
    )
    rng = np.random.default_rng(args.seed + 1)
    results = []
    for length in args.lengths:
        motions = sample_motions(
            checker, robot.arm_lower, robot.arm_upper, length, args.motions, rng
        )
        methods = {
            "batch": (checker, checker.check_motion),
            "serial": (checker_1, checker_1.check_motion),
        }
        verdicts: dict[str, list[bool]] = {}
        counts: dict[str, list[int]] = {}
        for name, (owner, method) in methods.items():  # verdicts, state counts, warm-up
            verdicts[name], counts[name] = [], []
            owner.forget()  # the sampling above remembered the motions' ends as free
            for a, b in motions:
                before = owner.states_checked
                verdicts[name].append(bool(method(a, b)))
                counts[name].append(owner.states_checked - before)
        for name in ("batch",):
            mismatch = sum(x != y for x, y in zip(verdicts[name], verdicts["serial"], strict=True))
            assert mismatch == 0, f"length {length}: {mismatch} {name} motion verdicts differ"
        valid = np.array(verdicts["batch"])

        # Per-motion times, every round runs both methods (order alternating).
        per_motion = {name: np.empty((args.motion_rounds, len(motions))) for name in methods}
        names = list(methods)
        gc.disable()
        try:
            for r in range(args.motion_rounds):
                order = names[r % len(names) :] + names[: r % len(names)]
                for name in order if r % 2 == 0 else order[::-1]:
                    owner, method = methods[name]
                    row = per_motion[name][r]
                    for i, (a, b) in enumerate(motions):
                        owner.forget()  # each motion checked whole, its end b included
                        started = time.perf_counter()
                        method(a, b)
                        row[i] = time.perf_counter() - started
        finally:
            gc.enable()

        subsets = {"all": np.ones(len(motions), bool), "valid": valid, "colliding": ~valid}
        entry: dict[str, Any] = {
            "length": length,
            "motions": len(motions),
            "valid_motions": int(valid.sum()),
            "resolution": checker.resolution,
            "threads": checker.world.num_threads,
            "rounds": args.motion_rounds,
        }
        for subset, mask in subsets.items():
            if not mask.any():
                continue
            stats = {}
            for name in names:
                states = int(np.asarray(counts[name])[mask].sum())
                totals = per_motion[name][:, mask].sum(axis=1)  # seconds per round
                total = float(np.median(totals))
                stats[name] = {
                    "states": states,
                    "median_s": total,
                    "us_per_motion": 1e6 * total / int(mask.sum()),
                    "us_per_state": 1e6 * total / states,
                }
            serial = per_motion["serial"][:, mask].sum(axis=1)
            for name in ("batch",):
                ratios = serial / per_motion[name][:, mask].sum(axis=1)
                stats[f"serial_over_{name}_time"] = float(np.median(ratios))
            stats["motions"] = int(mask.sum())
            entry[subset] = stats
        results.append(entry)
    return results


def fmt_us(seconds: float) -> str:
    return f"{seconds * 1e6:.2f}"


def warm_start_text(artifacts: dict[str, list[dict[str, Any]]]) -> str:
    if not artifacts:
        return "Every variant agreed with it on every state."
    parts = []
    for name, items in artifacts.items():
        kinds = {True: "colliding reported free", False: "free reported colliding"}
        states = ", ".join(f"{item['state']} ({kinds[item['valid']]})" for item in items[:5])
        more = f" and {len(items) - 5} more" if len(items) > 5 else ""
        parts.append(f"{name}: state {states}{more}")
    return (
        "Disagreements, all GJK warm-start artifacts (a fresh instance of the same check, "
        "with no query history, agrees with the reference): " + "; ".join(parts) + "."
    )


def report(info: dict, states: dict, motions: list[dict]) -> str:
    med = states["median_s_per_state"]
    coupled = med["coupled via OMPL"]
    out = [
        "## Coupled validity checker vs bare Pinocchio + Coal",
        "",
        _common.machine_line(info),
        "",
        f"{states['states']} uniform random arm configurations "
        f"({100 * states['valid_fraction']:.1f} % valid), median of {states['rounds']} "
        "interleaved rounds. Ratio = coupled via OMPL / variant.",
        "",
    ]
    labels = {
        "coupled via OMPL": "coupled checker via OMPL (`si.isValid`)",
        "bare OMPL checker": "bare OMPL checker, fixed hand, naive manager (`si.isValid`)",
        "bare naive": "bare Pinocchio+Coal, naive manager (world's type)",
        "bare naive, cold": "bare Pinocchio+Coal, naive manager, GJK warm start off",
        "bare tree": "bare Pinocchio+Coal, dynamic AABB tree manager",
        "bare pairs": "bare Pinocchio+Coal, pair loop",
    }
    rows = []
    for key, label in labels.items():
        t = med[key]
        rows.append([label, fmt_us(t), f"{1 / t:,.0f}", f"{coupled / t:.2f}"])
    out.append(_common.markdown_table(["variant", "µs/state", "checks/s", "ratio"], rows))
    out += [
        "",
        f"The fixed hand {states['fixed_hand']} (the law's plateau) changes the verdict of "
        f"{states['fixed_vs_law_verdicts_differ']} of {states['states']} states; the bare OMPL "
        "checker was verified on those fixed-hand configurations.",
        "",
        "Verdicts checked against Pinocchio's pair loop with Coal's GJK warm start off "
        "(`enable_cached_gjk_guess = False`; Pinocchio's default is on). "
        + warm_start_text(states["warm_start_artifacts"]),
        "",
        "### Where the coupled check's time goes",
        "",
    ]
    split = [
        ("coupled via OMPL", "coupled checker via OMPL (total)"),
        ("coupled, direct", "`checker.is_valid(list)` from Python (no OMPL)"),
        ("fill", "fill: FK + law into q (`checker._fill`)"),
        ("collision", "collision: naive-manager query on the world's context"),
        ("state read", "read the OMPL state (`state[0:7]`)"),
        ("empty loop", "loop overhead (list comprehension, nothing called)"),
    ]
    rows = [[label, fmt_us(med[key]), f"{100 * med[key] / coupled:.0f} %"] for key, label in split]
    rest = coupled - med["fill"] - med["collision"]
    rows.append(
        [
            "rest: OMPL dispatch, state read, Python calls (total - fill - collision)",
            fmt_us(rest),
            f"{100 * rest / coupled:.0f} %",
        ]
    )
    out.append(_common.markdown_table(["component", "µs/state", "share of total"], rows))
    out += [
        "",
        "## Motion validation: batched parallel vs one state at a time",
        "",
    ]
    if motions:
        out.append(
            f"{motions[0]['motions']} random straight motions per length between valid "
            f"configurations (lengths: Euclidean norm of the arm joint step), checker "
            f"resolution {motions[0]['resolution']:g}, "
            f"batches on {motions[0]['threads']} threads (the world's default) or 1, median of "
            f"{motions[0]['rounds']} interleaved rounds. States from `states_checked` deltas "
            "(the batch counts every state it submits). serial/method = time of the serial "
            "check / time of the method on the same motions (> 1: the method is faster)."
        )
        out.append("")
    labels = {
        "batch": f"batch, {motions[0]['threads'] if motions else '?'} threads (`check_motion`)",
        "serial": "one thread: the batch back end loops over the states one by one",
    }
    rows = []
    for entry in motions:
        for subset in ("all", "valid", "colliding"):
            if subset not in entry:
                continue
            s = entry[subset]
            for name, label in labels.items():
                m = s[name]
                ratio = 1.0 if name == "serial" else s[f"serial_over_{name}_time"]
                rows.append(
                    [
                        f"{entry['length']:g} rad, {subset}",
                        label,
                        s["motions"],
                        f"{m['states'] / s['motions']:.1f}",
                        f"{m['us_per_motion']:.0f}",
                        f"{m['us_per_state']:.2f}",
                        f"{ratio:.2f}",
                    ]
                )
    out.append(
        _common.markdown_table(
            ["motions", "method", "n", "states/motion", "µs/motion", "µs/state", "serial/method"],
            rows,
            left=2,
        )
    )
    return "\n".join(out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--scene", default=None, help="scene TOML (default: scenes/panda_can.toml, the Panda's can)"
    )
    parser.add_argument("--states", type=int, default=5000, help="random states (default 5000)")
    parser.add_argument("--rounds", type=int, default=11, help="interleaved rounds, states")
    parser.add_argument("--motions", type=int, default=300, help="motions per length (300)")
    parser.add_argument("--motion-rounds", type=int, default=5, help="interleaved rounds, motions")
    parser.add_argument(
        "--lengths", type=float, nargs="+", default=[0.3, 1.0], help="motion lengths [rad]"
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the random configurations")
    parser.add_argument("--skip-motions", action="store_true", help="only part A")
    parser.add_argument("--json", metavar="PATH", help="also write the results as JSON")
    args = parser.parse_args()
    if args.states < 1 or args.rounds < 1 or args.motions < 1 or args.motion_rounds < 1:
        parser.error("counts must be positive")

    ou.setLogLevel(ou.LOG_ERROR)
    scene = args.scene or openup_ompl.default_scene_path()
    problem = openup_ompl.load_scene(scene)
    setup = openup_ompl.GraspPlanningSetup(problem)
    info = _common.machine_info()

    started = time.perf_counter()
    states = bench_states(setup, args)
    print(f"states: {time.perf_counter() - started:.1f} s", file=sys.stderr)
    motions: list[dict] = []
    if not args.skip_motions:
        started = time.perf_counter()
        motions = bench_motions(setup, args)
        print(f"motions: {time.perf_counter() - started:.1f} s", file=sys.stderr)

    print(report(info, states, motions))
    _common.write_json(
        args.json,
        {
            "benchmark": "bench_validity",
            "machine": info,
            "scene": str(scene),
            "args": {k: v for k, v in vars(args).items() if k != "json"},
            "states": states,
            "motions": motions,
            "note": "times in seconds; ratios are medians over interleaved rounds",
        },
    )


if __name__ == "__main__":
    main()
