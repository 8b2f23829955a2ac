"""Contact pads against the URDF's collision boxes: the same plans and object errors
across the pads executed with the robot file's ``[physics] pads`` and without them
(``PhysicsOptions(pads=False)``), side by side.

"Across the pads" is the palm frame's x axis (for the Panda, the pads' width; its fingers
close along y), projected on the table. Each trial is one plan (a planning seed) and one
signed error; the counts carry Wilson 95 % intervals and the paired difference an exact
McNemar test (binomial on the discordant trials).

Run (about a minute on one core for the defaults: 3 plans x 4 errors x 2)::

    python benchmarks/physics_pads.py
    python benchmarks/physics_pads.py --scene scenes/panda_can.toml --seeds 10 \
        --deltas 0.01 0.015 0.02 0.03 --json pads.json
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
from scipy.stats import binomtest

sys.path.insert(0, str(Path(__file__).resolve().parent))

import _common  # noqa: E402

import openup_ompl as ou  # noqa: E402
from openup_ompl.physics import PhysicsOptions, Rollout  # noqa: E402

HERE = Path(__file__).resolve().parent
SCENE = HERE / "contact" / "panda_can_between_blocks.toml"


def across(problem: ou.Problem) -> np.ndarray:
    """Unit vector on the table along the palm frame's x axis at the grasp."""
    x = pin.XYZQUATToSE3(np.asarray(problem.grasp_pose)).rotation[:, 0].copy()
    x[2] = 0.0
    return x / np.linalg.norm(x)


def interval(k: int, n: int) -> str:
    """``k/n [low, high] %`` with Wilson's 95 % interval."""
    ci = binomtest(k, n).proportion_ci(method="wilson")
    return f"{k}/{n} [{ci.low * 100:.0f}, {ci.high * 100:.0f}] %"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default=str(SCENE))
    parser.add_argument("--seeds", type=int, default=3, help="plans (seeds 1..N)")
    parser.add_argument("--deltas", type=float, nargs="+", default=[0.01, 0.015])
    parser.add_argument("--json", default=None, help="also write the trials as JSON here")
    args = parser.parse_args()
    problem = ou.load_scene(args.scene)
    setup = ou.GraspPlanningSetup(problem)
    direction = across(problem)
    trials = []
    for seed in range(1, args.seeds + 1):
        plan = setup.solve(time_limit=10.0, seed=seed)
        rollouts = {pads: Rollout(plan, PhysicsOptions(pads=pads)) for pads in (False, True)}
        for delta in args.deltas:
            for sign in (-1.0, 1.0):
                dx, dy = (sign * delta * direction[:2]).tolist()
                row = {"seed": seed, "delta": delta, "sign": sign, "dx": dx, "dy": dy}
                for pads, rollout in rollouts.items():
                    record = rollout.run((dx, dy, 0.0), frames=False)
                    row["pads" if pads else "urdf"] = record.cause or "held"
                trials.append(row)
    rows = []
    for delta in [*args.deltas, None]:
        chosen = [t for t in trials if delta is None or t["delta"] == delta]
        urdf = [t["urdf"] == "held" for t in chosen]
        pads = [t["pads"] == "held" for t in chosen]
        gained = sum(p and not u for u, p in zip(urdf, pads, strict=True))
        lost = sum(u and not p for u, p in zip(urdf, pads, strict=True))
        p = binomtest(gained, gained + lost).pvalue if gained + lost else 1.0
        causes = sorted({t["urdf"] for t in chosen} | {t["pads"] for t in chosen})
        rows.append([
            "all" if delta is None else f"{delta * 100:g} cm",
            interval(sum(urdf), len(urdf)), interval(sum(pads), len(pads)),
            f"{gained} / {lost}", f"{p:.3g}", ", ".join(causes),
        ])  # fmt: skip
    print(f"{Path(args.scene).name}: {args.seeds} plans, errors +- delta across the pads")
    print(
        _common.markdown_table(
            [
                "error",
                "held, URDF boxes",
                "held, pads",
                "pads gain / lose",
                "McNemar p",
                "outcomes seen",
            ],
            rows,
        )  # fmt: skip
    )
    print(_common.machine_line(_common.machine_info()))
    _common.write_json(args.json, {"machine": _common.machine_info(), "trials": trials})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
