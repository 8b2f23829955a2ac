"""The shared approach (``PhysicsOptions.shared_approach``) against unshared rollouts on
scenes beyond the fixed trial sets: the same verdicts, how many trials share, the time.

For each scene and planning seed, one plan (IKBiRRT, 5 s) executed against the sweep's 21
offsets of the object (nominal, then +-x and +-y at 0.5, 1, 1.5, 2 and 3 cm; all turned
by ``--yaw`` about the object's own z axis), once with
the approach shared and once without, as a physics sweep does (``early_end``). A verdict
(success and cause) that differs is then probed: the unshared trial again with its
object's start moved by 1e-12, 1e-10 and 1e-8 m along x, then along y, and turned by as
many radians; if one of those turns its verdict, rounding decides it
(``benchmarks/physics_sensitivity.py``).

Run (about 3 minutes on one core with the defaults: the ten unseen and held-out Panda
scenes and the three shipped ones other than the Panda can, two plans each)::

    python benchmarks/physics_shared_check.py
    python benchmarks/physics_shared_check.py --scenes scenes/panda_can.toml --seeds 1 2 3
    python benchmarks/physics_shared_check.py --yaw 0.4
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(ROOT / "tests"))

import _common  # noqa: E402
import physics_regression as regression  # noqa: E402

import openup_ompl as oo  # noqa: E402
from openup_ompl.physics import PhysicsOptions, Rollout  # noqa: E402
from openup_ompl.study.stats import wilson_interval  # noqa: E402

SCENES = [
    *sorted((ROOT / "benchmarks" / "unseen" / "panda").glob("*.toml")),
    *sorted((ROOT / "benchmarks" / "heldout" / "panda").glob("*.toml")),
    ROOT / "scenes" / "ur5_allegro_can.toml",
    ROOT / "scenes" / "lwa3_sdh_can.toml",
    ROOT / "scenes" / "panda_bottle.toml",
]
PROBES = (1e-12, 1e-10, 1e-8)


def verdict(record: oo.ExecutionRecord) -> str:
    """``held`` or the failure cause."""
    return record.cause or "held"


def check(scene: Path, seed: int, yaw: float = 0.0) -> dict[str, object]:
    """One plan of ``scene`` at the sweep's offsets (turned by ``yaw`` [rad]), shared
    and unshared."""
    problem = oo.load_scene(scene)
    plan = oo.GraspPlanningSetup(problem).solve(time_limit=5.0, planner="ikbirrt", seed=seed)
    shared = Rollout(plan, PhysicsOptions(early_end=True, shared_approach=True))
    plain = Rollout(plan, PhysicsOptions(early_end=True))
    times, trials = [0.0, 0.0], []
    for dx, dy, _ in regression.SWEEP:
        offset = [dx, dy, yaw]
        started = time.perf_counter()
        a = shared.run(offset, frames=False)
        times[0] += time.perf_counter() - started
        started = time.perf_counter()
        b = plain.run(offset, frames=False)
        times[1] += time.perf_counter() - started
        shared._start(offset[0], offset[1], 0, offset[2])
        world = shared.world
        start = shared.sim.qpos[world.object_qpos : world.object_qpos + 7].copy()
        handover = shared._shared.handover(start) if shared._shared else None
        trial = {"offset": offset, "shared": verdict(a), "unshared": verdict(b),
                 "handover": handover.end if handover else None}  # fmt: skip
        if verdict(a) != verdict(b):
            probes = {}
            for axis, name in enumerate(("x", "y", "yaw")):
                for eps in PROBES:
                    moved = list(offset)
                    moved[axis] += eps
                    probes[f"{name} {eps:g}"] = verdict(plain.run(moved, frames=False))
            trial["probes"] = probes
        trials.append(trial)
    return {"scene": scene.name, "seed": seed, "seconds": times, "trials": trials}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenes", type=Path, nargs="+", default=SCENES)
    parser.add_argument("--seeds", type=int, nargs="+", default=[11, 12])
    parser.add_argument("--yaw", type=float, default=0.0, help="every offset's turn [rad]")
    parser.add_argument("--json", type=Path, help="write the trials here")
    args = parser.parse_args()
    runs = []
    for scene in args.scenes:
        for seed in args.seeds:
            run = check(scene, seed, args.yaw)
            runs.append(run)
            trials = run["trials"]
            shared = sum(t["handover"] is not None for t in trials)  # type: ignore[attr-defined]
            print(f"{scene.name} seed {seed}: {shared} of {len(trials)} trials shared",  # type: ignore[arg-type]
                  flush=True)  # fmt: skip
    trials = [t for run in runs for t in run["trials"]]  # type: ignore[attr-defined]
    same = sum(t["shared"] == t["unshared"] for t in trials)
    shared = sum(t["handover"] is not None for t in trials)
    low, high = wilson_interval(same, len(trials))
    seconds = [sum(run["seconds"][i] for run in runs) for i in (0, 1)]  # type: ignore[index]
    print(f"same verdict: {same} of {len(trials)} ({100 * same / len(trials):.1f} %, 95 % CI "
          f"{100 * low:.1f}-{100 * high:.1f} %); shared: {shared}; unshared / shared time "
          f"{seconds[1] / seconds[0]:.2f}x")  # fmt: skip
    for run in runs:
        for t in run["trials"]:  # type: ignore[attr-defined]
            if t["shared"] != t["unshared"]:
                decided = any(v != t["unshared"] for v in t["probes"].values())
                turned = [k for k, v in t["probes"].items() if v != t["unshared"]]
                print(f"  {run['scene']} seed {run['seed']} at {t['offset']}: unshared "
                      f"{t['unshared']}, shared {t['shared']}; turned by the start moved "
                      + (", ".join(turned) if turned else "by none of the probes")
                      + ("  (rounding decides it)" if decided else ""))  # fmt: skip
    print(_common.machine_line(_common.machine_info()))
    if args.json:
        args.json.write_text(json.dumps({"machine": _common.machine_info(), "runs": runs},
                                        indent=1, default=str) + "\n")  # fmt: skip


if __name__ == "__main__":
    main()
