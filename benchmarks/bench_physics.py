"""Cost of one physics trial (MuJoCo rollout) per robot, against one kinematic trial.

For each scene, one plan (ikbirrt, seed 1, as the robustness sweep makes them) is
executed ``--trials`` times at the sweep's perturbations (cycled): kinematically
(:func:`openup_ompl.robustness.execute`: the re-check of every row against the true
scene and the hand closing) and in physics (:class:`openup_ompl.physics.Rollout`: settle,
reach, close, lift, hold; the world built once per plan as the sweep does). Reported:
wall time per trial (median), simulated seconds per wall second, steps per trial, the
physics / kinematic ratio, and the projected wall time of a default physics sweep (50
plans x 21 perturbations = 1050 trials) on ``--workers`` processes, planning included.

Run (about 1 min on 2 idle cores)::

    python benchmarks/bench_physics.py
    python benchmarks/bench_physics.py --trials 42 --json bench_physics.json
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import _common  # noqa: E402

import openup_ompl  # noqa: E402
from openup_ompl.physics import Rollout  # noqa: E402
from openup_ompl.robustness import execute, perturbations  # noqa: E402

SCENES = Path(__file__).resolve().parent.parent / "scenes"
DEFAULT_SCENES = [
    SCENES / f"{name}.toml" for name in ("lwa3_sdh_can", "panda_can", "ur5_allegro_can")
]
#: The default sweep: 5 u x 10 seeds plans, 21 perturbations each.
SWEEP_PLANS, SWEEP_CELLS = 50, 21


def measure(scene: Path, trials: int, workers: int) -> dict[str, object]:
    problem = openup_ompl.load_scene(scene)
    setup = openup_ompl.GraspPlanningSetup(problem)
    started = time.perf_counter()
    plan = setup.solve(time_limit=5.0, planner="ikbirrt", seed=1, simplify=True)
    plan_s = time.perf_counter() - started
    cells = perturbations((0.0, 0.005, 0.01, 0.015, 0.02, 0.03))
    offsets = [cells[i % len(cells)] for i in range(trials)]
    kinematic = []
    for dx, dy, yaw in offsets:
        started = time.perf_counter()
        execute(setup, plan, dx, dy, yaw, torsion=problem.robot.spec.torsion)
        kinematic.append(time.perf_counter() - started)
    started = time.perf_counter()
    rollout = Rollout(plan)
    build_s = time.perf_counter() - started
    physics, steps = [], []
    for offset in offsets:
        started = time.perf_counter()
        record = rollout.run(offset, frames=False)
        physics.append(time.perf_counter() - started)
        steps.append(record.steps)
    timestep = rollout.options.timestep
    per_trial = _common.median(physics)
    sweep_s = (SWEEP_PLANS * (plan_s + build_s) + SWEEP_PLANS * SWEEP_CELLS * per_trial) / workers
    return {
        "scene": scene.stem,
        "trials": trials,
        "kinematic_ms": _common.median(kinematic) * 1e3,
        "physics_ms": per_trial * 1e3,
        "build_ms": build_s * 1e3,
        "steps": _common.median(steps),
        "sim_per_wall": _common.median(steps) * timestep / per_trial,
        "ratio": per_trial / _common.median(kinematic),
        "plan_ms": plan_s * 1e3,
        "sweep_min": sweep_s / 60,
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--scenes",
        type=Path,
        nargs="+",
        default=DEFAULT_SCENES,
        help="scene files (default: every robot's demo scene, scenes/*_can.toml)",
    )
    parser.add_argument("--trials", type=int, default=21, help="trials per scene and kind")
    parser.add_argument("--workers", type=int, default=2, help="processes of the projection")
    parser.add_argument("--json", default=None, help="write the results to this JSON file")
    args = parser.parse_args()
    missing = [str(s) for s in args.scenes if not s.is_file()]
    if missing:
        parser.error(f"--scenes: no such file {missing[0]} (give scene files' paths)")
    if args.trials < 1 or args.workers < 1:
        parser.error("--trials and --workers must be >= 1")
    from ompl import util as ompl_util

    ompl_util.RNG.setSeed(1)
    ompl_util.setLogLevel(ompl_util.LOG_ERROR)
    info = _common.machine_info()
    rows = []
    for scene in args.scenes:
        print(f"{scene.stem} ...", file=sys.stderr, flush=True)
        rows.append(measure(scene, args.trials, args.workers))
    print(_common.machine_line(info))
    print()
    print(
        _common.markdown_table(
            [
                "scene",
                "kinematic ms/trial",
                "physics ms/trial",
                "physics / kinematic",
                "steps/trial",
                "sim s / wall s",
                "world build ms",
                f"1050-trial sweep, {args.workers} workers [min]",
            ],
            [
                [
                    r["scene"],
                    f"{r['kinematic_ms']:.1f}",
                    f"{r['physics_ms']:.0f}",
                    f"{r['ratio']:.0f}x",
                    f"{r['steps']:.0f}",
                    f"{r['sim_per_wall']:.0f}",
                    f"{r['build_ms']:.0f}",
                    f"{r['sweep_min']:.1f}",
                ]
                for r in rows
            ],
        )
    )
    _common.write_json(args.json, {"machine": info, "rows": rows})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
