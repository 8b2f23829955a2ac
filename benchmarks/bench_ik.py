"""IK solve time and success rate on the grasps of the problem suite.

For each scene, ``IKSolver.refine`` runs from the same uniformly random arm
configurations (seeded); one refine is one IK restart. Reported per scene: the success
rate of one restart, µs per restart, damped least-squares iterations per restart
(``IKSolver.iterations``), µs per iteration, and the cost of one *solution* (time of all
restarts / solutions found), also as a ratio to a reference measured in the same run:
one forward kinematics + frame Jacobian (``pin.forwardKinematics`` +
``pin.computeFrameJacobian``, the work one iteration cannot avoid). "collision-free" is
the share of solutions that pass the coupled check with the hand at ``c`` (the goal's
test).

Run (about 20 s on 2 idle cores)::

    python benchmarks/bench_ik.py
    python benchmarks/bench_ik.py --restarts 400 --json bench_ik.json
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import pinocchio as pin

sys.path.insert(0, str(Path(__file__).resolve().parent))

import _common  # noqa: E402

import openup_ompl  # noqa: E402
from openup_ompl.ik import IKSolver  # noqa: E402
from openup_ompl.validity import CoupledChecker  # noqa: E402


def fk_jacobian_us(robot: openup_ompl.Robot, arms: np.ndarray) -> float:
    """µs for one forward kinematics + palm frame Jacobian, median of 5 rounds."""
    model, data = robot.model, robot.model.createData()
    q = pin.neutral(model)
    rounds = []
    for _ in range(5):
        started = time.perf_counter()
        for arm in arms:
            q[robot.arm_idx] = arm
            pin.forwardKinematics(model, data, q)
            pin.computeFrameJacobian(model, data, q, robot.palm_frame_id, pin.LOCAL)
        rounds.append((time.perf_counter() - started) / len(arms) * 1e6)
    return _common.median(rounds)


def measure(scene: Path, restarts: int, seed: int) -> dict[str, object]:
    problem = openup_ompl.load_scene(scene)
    robot = problem.robot
    solver = IKSolver(robot, problem.grasp)
    rng = np.random.default_rng(seed)
    arms = np.array([solver.random_arm(rng) for _ in range(restarts)])
    reference = fk_jacobian_us(robot, arms)
    started = time.perf_counter()
    solutions = [s for s in (solver.refine(a) for a in arms) if s is not None]
    elapsed = time.perf_counter() - started
    checker = CoupledChecker(problem, problem.hand_law)
    free = sum(bool(checker.is_valid(s)) for s in solutions)
    per_solution = elapsed / len(solutions) * 1e6 if solutions else float("nan")
    return {
        "scene": scene.stem,
        "restarts": restarts,
        "success": len(solutions) / restarts,
        "us_per_restart": elapsed / restarts * 1e6,
        "iterations_per_restart": solver.iterations / solver.calls,
        "us_per_iteration": elapsed / solver.iterations * 1e6,
        "us_per_solution": per_solution,
        "fk_jacobian_us": reference,
        "solution_over_fk_jacobian": per_solution / reference,
        "collision_free": free / len(solutions) if solutions else float("nan"),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--scenes",
        type=Path,
        nargs="+",
        default=sorted((Path(__file__).parent / "problems" / "panda").glob("*.toml")),
        help="scene files (default: the Panda suite)",
    )
    parser.add_argument("--restarts", type=int, default=200, help="IK restarts per scene")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--json", default=None, help="write the results to this JSON file")
    args = parser.parse_args()
    if args.restarts < 1:
        parser.error("--restarts must be >= 1")
    missing = [str(s) for s in args.scenes if not Path(s).is_file()]
    if missing:
        parser.error(f"--scenes: no such file {missing[0]}")
    info = _common.machine_info()
    rows = []
    for scene in args.scenes:
        print(f"{scene.stem} ...", file=sys.stderr, flush=True)
        rows.append(measure(scene, args.restarts, args.seed))
    print(_common.machine_line(info))
    print()
    print(
        _common.markdown_table(
            [
                "scene",
                "success/restart",
                "µs/restart",
                "iter/restart",
                "µs/iter",
                "µs/solution",
                "FK+J µs",
                "solution / FK+J",
                "collision-free",
            ],
            [
                [
                    r["scene"],
                    f"{100 * r['success']:.0f} %",
                    f"{r['us_per_restart']:.0f}",
                    f"{r['iterations_per_restart']:.1f}",
                    f"{r['us_per_iteration']:.1f}",
                    f"{r['us_per_solution']:.0f}",
                    f"{r['fk_jacobian_us']:.1f}",
                    f"{r['solution_over_fk_jacobian']:.0f}x",
                    f"{100 * r['collision_free']:.0f} %",
                ]
                for r in rows
            ],
        )
    )
    _common.write_json(args.json, {"machine": info, "rows": rows})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
