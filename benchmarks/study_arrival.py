"""How much of the hand law's extra opening is left when the fingertips reach the object.

For instances of the study's families (no physics, no planning), per family: the clearance
per side that ``u = 1`` buys at the maximum aperture (``k``,
:func:`~openup_ompl.perception.uncertainty.clearance_per_u`), the share of it left where a
straight final approach brings the fingertips to the object's near side
(:func:`~openup_ompl.perception.uncertainty.arrival_fraction`), and the largest error the
fully open hand then covers at two standard deviations, ``f k / 2``, against which the
study's direct errors (sigma 0.5, 1, 2 cm) compare. Algorithm 3 closes the hand linearly
from ``mga`` to the grasp, so the clearance at distance ``d`` is ``k u min(1, d / mga)``:
the figure draws it for ``u = 1`` with each family's arrival marked.

Run::

    python benchmarks/study_arrival.py --out docs/results/study_arrival.png
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from openup_ompl.perception.uncertainty import arrival_fraction, clearance_per_u
from openup_ompl.study.families import instance_problem, parse_families, template_scene
from openup_ompl.study.run import trial_seeds
from openup_ompl.viz._mpl import _pyplot, _save

ROBOTS = ("panda", "lwa3_sdh")


def family_rows(robot: str, instances: int, mesh_dir: Path) -> list[dict[str, float | str]]:
    """Per family of ``robot``: mean ``k`` [m], mean arrival share, the law's ``mga``."""
    rows: list[dict[str, float | str]] = []
    for family in parse_families([f"{robot}-all"]):
        template = template_scene(family)
        ks, shares = [], []
        for i in range(instances):
            rng, _, _ = trial_seeds(3, family.name, "pose-1cm", i)
            problem = instance_problem(family, rng, template, mesh_dir)
            ks.append(clearance_per_u(problem))
            shares.append(arrival_fraction(problem))
        k, share = float(np.mean(ks)), float(np.mean(shares))
        rows.append({
            "family": family.name, "k": k, "share": share, "share_min": float(np.min(shares)),
            "share_max": float(np.max(shares)), "mga": template.hand_law.mga,
            "covered": share * k / 2,
        })  # fmt: skip
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--instances", type=int, default=50, help="instances per family")
    parser.add_argument("--out", type=Path, default=Path("study_arrival.png"))
    parser.add_argument("--mesh-dir", type=Path, default=Path("study_arrival_meshes"))
    args = parser.parse_args()
    plt = _pyplot()
    fig, axes = plt.subplots(1, len(ROBOTS), figsize=(11, 3.8))
    print("| family | k at mga [mm] | share left at arrival | largest sigma u = 1 covers [mm] |")
    print("|:--|--:|:--|--:|")
    for ax, robot in zip(axes, ROBOTS, strict=True):
        rows = family_rows(robot, args.instances, args.mesh_dir.resolve())
        d = np.linspace(0.0, 1.0, 201)
        for row in rows:
            share, name = float(row["share"]), str(row["family"]).split("-", 1)[1]
            k, mga = float(row["k"]), float(row["mga"])
            (line,) = ax.plot(d, 1e3 * k * np.minimum(1.0, d / mga), lw=1, label=name)
            ax.plot(share * mga, 1e3 * k * share, "o", color=line.get_color())
            print(
                f"| {row['family']} | {1e3 * k:.1f} | {share:.2f}"
                f" ({float(row['share_min']):.2f}-{float(row['share_max']):.2f})"
                f" | {1e3 * float(row['covered']):.1f} |"
            )
        for sigma in (0.005, 0.01, 0.02):
            ax.axhline(2e3 * sigma, ls=":", color="tab:gray")
            ax.text(1.0, 2e3 * sigma, f"2σ, σ = {100 * sigma:g} cm", ha="right", va="bottom",
                    fontsize=7, color="tab:gray")  # fmt: skip
        ax.set_ylim(0, max(45.0, 1.15e3 * max(float(r["k"]) for r in rows)))
        ax.set_xlabel("normalised palm distance d (0: grasp)")
        ax.set_ylabel("clearance per side u = 1 buys [mm]")
        ax.set_title(f"{robot}: where the fingertips reach the object (dots)", fontsize=9)
        ax.legend(fontsize=7, loc="upper left", ncol=2)
    _save(fig, args.out, 150)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
