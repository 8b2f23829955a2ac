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


def figure(path: str) -> None:
    """Draw the Panda's left finger's contact geometry: its URDF fingertip box and the
    robot file's pads, from the front (x-z, looking along the closing axis) and from the
    side (y-z), in the finger's frame [mm]."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    from openup_ompl.robot_file import RobotSpec, find_robot_file

    pads = [p for p in RobotSpec.from_file(find_robot_file("panda")).pads
            if p.link == "panda_leftfinger"]  # fmt: skip
    tip = ([0.0, 7.58, 45.25], [17.5, 15.2, 18.5])  # the URDF's fingertip box [mm]
    fig, axes = plt.subplots(1, 2, figsize=(8, 4.2))
    for ax, (a, b), title in zip(
        axes,
        ((0, 2), (1, 2)),
        ("front (x, z): the pads' faces", "side (y, z): the can at y < 0"),
        strict=True,
    ):
        centre, size = tip
        ax.add_patch(Rectangle((centre[a] - size[a] / 2, centre[b] - size[b] / 2), size[a],
                               size[b], fill=False, ls="--", lw=1.5, ec="0.3",
                               label="URDF fingertip box (obstacles only)"))  # fmt: skip
        names = ["pad box", "corner boxes (touch first)", None, None, None,
                 "fingertip behind, recessed 4 mm"]  # fmt: skip
        colours = ["C1", "C0", "C0", "C0", "C0", "C2"]
        for k in (5, 0, 1, 2, 3, 4):  # the recessed fingertip first, the corners on top
            pad, name, colour = pads[k], names[k], colours[k]
            c, s = pad.pose[:3] * 1e3, pad.size * 1e3
            corner = (c[a] - s[a] / 2, c[b] - s[b] / 2)
            alpha = 0.25 if k == 5 else 0.7
            ax.add_patch(Rectangle(corner, s[a], s[b], alpha=alpha, color=colour, label=name))
        ax.set_xlim(-14, 14) if a == 0 else ax.set_xlim(-6, 20)
        ax.set_ylim(58, 32)
        ax.set_aspect("equal")
        ax.set_xlabel("x [mm]" if a == 0 else "y [mm] (the finger's inner face at 0)")
        ax.set_ylabel("z [mm] (along the finger)")
        ax.set_title(title, fontsize=10)
    fig.legend(*axes[0].get_legend_handles_labels(), fontsize=8, loc="lower center", ncol=2)
    fig.suptitle("Panda left finger: physics contact pads (robots/panda.toml) and the URDF box")
    fig.tight_layout(rect=(0, 0.12, 1, 1))
    fig.savefig(path, dpi=110)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default=str(SCENE))
    parser.add_argument("--seeds", type=int, default=3, help="plans (seeds 1..N)")
    parser.add_argument("--deltas", type=float, nargs="+", default=[0.01, 0.015])
    parser.add_argument("--json", default=None, help="also write the trials as JSON here")
    parser.add_argument("--figure", default=None, help="only draw the Panda's pads to this PNG")
    args = parser.parse_args()
    if args.figure:
        figure(args.figure)
        return 0
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
