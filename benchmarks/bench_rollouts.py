"""Physics rollouts per second per worker, before and after the rollout's speed-ups, side
by side.

The workload is the throughput set of ``tests/data/physics_trials.json`` (six stored
plans: the Panda's can twice, LWA3-SDH, UR5-Allegro, the bottle with its movable cup
twice; ``--per-plan`` of the sweep's 21 perturbations each), run as a sweep worker runs
it: one :class:`~openup_ompl.physics.Rollout` per plan (built from the plan's file
contents), every perturbation through it, no frames. "Before" is the package at
``--baseline`` (a git revision, extracted with ``git archive``; default: the parent of
the first commit whose message starts with "Rollout speed-ups"), "after" this tree with the
sweep's settings (``PhysicsOptions(early_end=True)``; compiled worlds reused across plans
of one scene). Each run is a fresh worker process; the runs alternate before / after
``--rounds`` times, so both see the same machine load; the ratio is per round, then its
median, of the rates over wall-clock time and of the workers' CPU times (the second moves
less with other processes' load). The verdicts of both are compared trial by trial.
``--shared`` adds a third worker a round: "after" with ``PhysicsOptions.shared_approach``
(the plan's trials share its approach; equal up to rounding, so its verdicts are counted
against "before"'s rather than required equal).

Run (about 3 minutes on one busy core with the defaults)::

    python benchmarks/bench_rollouts.py
    python benchmarks/bench_rollouts.py --rounds 5 --per-plan 21 --json rollouts.json
    python benchmarks/bench_rollouts.py --rounds 3 --per-plan 21 --shared
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import _common  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
MARK = "Rollout speed-ups"


def worker(per_plan: int, fast: bool, shared: bool = False) -> dict[str, object]:
    """Run the workload in this process; returns rollouts, seconds and verdicts."""
    sys.path.insert(0, str(ROOT / "tests"))
    import dataclasses

    import physics_regression as regression

    from openup_ompl.physics import PhysicsOptions, Rollout

    names = {f.name for f in dataclasses.fields(PhysicsOptions)}
    options = PhysicsOptions(early_end=True) if fast and "early_end" in names else None
    if shared:
        options = PhysicsOptions(early_end=True, shared_approach=True)
    cases = regression.load(regression.TRIALS)
    contents = [regression.plan_contents(case) for case in cases]  # not timed: the plans
    verdicts, steps = [], 0
    started, cpu = time.perf_counter(), time.process_time()
    for case, data in zip(cases, contents, strict=True):
        rollout = Rollout(data, options)
        for trial in case["trials"][:per_plan]:
            record = rollout.run(trial["offset"], frames=False)
            verdicts.append([record.success, record.cause])
            steps += record.steps
    seconds, cpu = time.perf_counter() - started, time.process_time() - cpu
    return {"rollouts": len(verdicts), "seconds": seconds, "cpu_seconds": cpu, "steps": steps,
            "verdicts": verdicts}  # fmt: skip


def _baseline_revision() -> str:
    found = subprocess.run(
        ["git", "log", f"--grep=^{MARK}", "--format=%H"],
        cwd=ROOT, capture_output=True, text=True, check=False,
    ).stdout.split()[-1:]  # fmt: skip
    if not found:
        raise SystemExit(f"no commit starting with {MARK!r}: pass --baseline REV")
    return f"{found[0]}~1"


def _extract(revision: str, into: Path) -> Path:
    """The package of ``revision`` unpacked under ``into``; returns the root."""
    archive = into / "baseline.tar"
    subprocess.run(
        ["git", "archive", "--format=tar", "-o", str(archive), revision, "openup_ompl", "robots"],
        cwd=ROOT, check=True,
    )  # fmt: skip
    with tarfile.open(archive) as tar:
        tar.extractall(into / "baseline", filter="data")
    return into / "baseline"


def _run(package_root: Path, per_plan: int, fast: bool, shared: bool = False) -> dict[str, object]:
    """One worker process with ``package_root`` first on its path."""
    env = {**os.environ, "PYTHONPATH": str(package_root)}
    args = [sys.executable, __file__, "--worker", "--per-plan", str(per_plan)]
    flags = (["--fast"] if fast else []) + (["--shared"] if shared else [])
    out = subprocess.run(
        [*args, *flags], env=env, capture_output=True, text=True, check=True,
    )  # fmt: skip
    result: dict[str, object] = json.loads(out.stdout.strip().splitlines()[-1])
    return result


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", default=None, help="git revision of 'before'")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--per-plan", type=int, default=7, help="perturbations per plan (<= 21)")
    parser.add_argument("--json", default=None)
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--fast", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument(
        "--shared", action="store_true",
        help="also run 'after' with PhysicsOptions.shared_approach (a third worker a round)",
    )  # fmt: skip
    args = parser.parse_args()
    if args.worker:
        print(json.dumps(worker(args.per_plan, args.fast, args.shared)))
        return 0
    revision = args.baseline or _baseline_revision()
    info = _common.machine_info()
    rows, runs = [], []
    with tempfile.TemporaryDirectory() as tmp:
        before_root = _extract(revision, Path(tmp))
        for round_ in range(args.rounds):
            before = _run(before_root, args.per_plan, fast=False)
            after = _run(ROOT, args.per_plan, fast=True)
            runs.append({"before": before, "after": after})
            rate_before = before["rollouts"] / before["seconds"]  # type: ignore[operator]
            rate_after = after["rollouts"] / after["seconds"]  # type: ignore[operator]
            cpu_ratio = before["cpu_seconds"] / after["cpu_seconds"]  # type: ignore[operator]
            same = before["verdicts"] == after["verdicts"]
            row = [
                round_ + 1, before["rollouts"], f"{rate_before:.2f}", f"{rate_after:.2f}",
                f"{rate_after / rate_before:.2f}x", f"{cpu_ratio:.2f}x",
                f"{before['steps']} / {after['steps']}", "yes" if same else "NO",
            ]  # fmt: skip
            if args.shared:
                shared = _run(ROOT, args.per_plan, fast=True, shared=True)
                runs[-1]["shared"] = shared
                rate = shared["rollouts"] / shared["seconds"]  # type: ignore[operator]
                pairs = zip(before["verdicts"], shared["verdicts"], strict=True)  # type: ignore[call-overload]
                changed = sum(a != b for a, b in pairs)
                row += [f"{rate:.2f}", f"{rate / rate_before:.2f}x", changed]
            rows.append(row)
    ratios = [float(r[4].rstrip("x")) for r in rows]
    cpu_ratios = [float(r[5].rstrip("x")) for r in rows]
    print(f"baseline {revision}; {args.per_plan} perturbations x 6 plans per run")
    print(
        _common.markdown_table(
            [
                "round",
                "rollouts",
                "before [rollouts/s]",
                "after [rollouts/s]",
                "after / before",
                "CPU time before / after",
                "steps before / after",
                "same verdicts",
                *(
                    ["shared [rollouts/s]", "shared / before", "verdicts changed (shared)"]
                    if args.shared
                    else []
                ),
            ],
            rows,
        )  # fmt: skip
    )
    print(
        f"median ratio {_common.median(ratios):.2f}x (CPU time"
        f" {_common.median(cpu_ratios):.2f}x) over {args.rounds} rounds"
    )
    if args.shared:
        shared_ratios = [float(r[9].rstrip("x")) for r in rows]
        print(f"shared approach: median ratio {_common.median(shared_ratios):.2f}x")
    print(_common.machine_line(info))
    _common.write_json(args.json, {"machine": info, "baseline": revision, "runs": runs})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
