"""Cost of closing the hand until contact, and of the force-closure test.

For each robot's demo scene, the hand is closed from collision-free IK solutions of the
grasp pose (the hand at the law's grasp opening), with the object at its nominal pose
and displaced by 1 cm along +y: reported per robot are the median time of one closing
[ms], its rounds of distance queries, the finger-object distance at the stops (it must
not exceed the 0.5 mm tolerance), how many grasps are in force closure (with the robot
file's ``[hand].torsion``) and the median time of one force-closure linear program.
The time of one closing is compared, in the same run, with one ``pin.computeDistances``
over the same geometry model (every finger-shape pair at once).

Run (about 20 s)::

    python benchmarks/bench_grasp.py
    python benchmarks/bench_grasp.py --solutions 10 --json bench_grasp.json
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import pinocchio as pin

sys.path.insert(0, str(Path(__file__).resolve().parent))

import _common  # noqa: E402

import openup_ompl as oo  # noqa: E402
from openup_ompl._resources import data_dir  # noqa: E402
from openup_ompl.grasp import HandCloser, force_closure  # noqa: E402
from openup_ompl.planning import GraspPlanningSetup  # noqa: E402
from openup_ompl.robustness import displaced  # noqa: E402

SCENES = ("panda_can.toml", "lwa3_sdh_can.toml", "ur5_allegro_can.toml")


def measure(scene: str, solutions: int, repeats: int) -> dict[str, object]:
    problem = oo.load_scene(data_dir("scenes") / scene)
    setup = GraspPlanningSetup(problem)
    goal = setup.goal
    while len(goal.solutions) < solutions:
        goal.sample()
    qs = [setup.checker.coupled_q(arm) for arm in goal.solutions[:solutions]]
    times, steps, gaps, lp_times, closures = [], [], [], [], []
    for true in (problem, displaced(problem, 0.0, 0.01)):
        closer = HandCloser(true)
        for q in qs:
            for _ in range(repeats):
                started = time.perf_counter()
                result = closer.close(q)
                times.append(time.perf_counter() - started)
            steps.append(result.steps)
            gaps += [c.distance for c in result.contacts]
            if result.contacts:
                started = time.perf_counter()
                closures.append(
                    force_closure(result.points, result.normals, torsion=problem.robot.spec.torsion)
                )
                lp_times.append(time.perf_counter() - started)
    model, geometry_model = problem.robot.model, closer.geometry_model
    data, geometry_data = model.createData(), geometry_model.createData()
    reference = []
    for q in qs:
        started = time.perf_counter()
        pin.computeDistances(model, data, geometry_model, geometry_data, q)
        reference.append(time.perf_counter() - started)
    close_ms = _common.median(times) * 1e3
    return {
        "robot": problem.robot.name,
        "close_ms": close_ms,
        "rounds": _common.median(steps),
        "max_gap_mm": max(gaps) * 1e3 if gaps else None,
        "lp_ms": _common.median(lp_times) * 1e3 if lp_times else None,
        "force_closure": f"{sum(closures)}/{len(closures)}",
        "all_pairs_ms": _common.median(reference) * 1e3,
        "pairs": len(geometry_model.collisionPairs),
        "ratio": close_ms / (_common.median(reference) * 1e3),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--solutions", type=int, default=5, help="IK solutions per scene")
    parser.add_argument("--repeats", type=int, default=5, help="closings per solution")
    parser.add_argument("--json", default=None, help="also write the results here")
    args = parser.parse_args()
    if args.solutions < 1 or args.repeats < 1:
        parser.error("--solutions and --repeats must be >= 1")
    rows = [measure(scene, args.solutions, args.repeats) for scene in SCENES]
    info = _common.machine_info()
    print(_common.machine_line(info))
    header = (
        "robot", "closing [ms]", "query rounds", "max stop gap [mm]", "force closure",
        "LP [ms]", "all pairs once [ms]", "closing / all pairs",
    )  # fmt: skip
    table = [
        (
            r["robot"],
            f"{r['close_ms']:.1f}",
            f"{r['rounds']:.0f}",
            f"{r['max_gap_mm']:.3f}",
            r["force_closure"],
            f"{r['lp_ms']:.2f}",
            f"{r['all_pairs_ms']:.3f} ({r['pairs']} pairs)",
            f"{r['ratio']:.0f}",
        )
        for r in rows
    ]
    print(_common.markdown_table(header, table))
    _common.write_json(args.json, {"machine": info, "rows": rows})


if __name__ == "__main__":
    main()
