"""Two views fused (``openup_ompl.perception.fuse``) against each alone: per sensor noise
and seed, ``u``, the position error and the position's standard deviation (the square
root of the covariance's trace) of the scene's camera, of a second camera turned about the
object, and of their fusion.

    python benchmarks/perception_fusion.py                      # the pillars' can, exact
    python benchmarks/perception_fusion.py --defaults           # with calibration errors
    python benchmarks/perception_fusion.py --scene benchmarks/unseen/panda/wall_window.toml

The first view of seed ``s`` is seeded ``s``, the second ``s + 100``; one fit per view.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import _common  # noqa: E402

import openup_ompl as oo  # noqa: E402
from openup_ompl.perception import NoiseOptions, fuse, perceive  # noqa: E402
from openup_ompl.perception.camera import DepthCamera, camera_of_scene  # noqa: E402
from openup_ompl.perception.extrinsic import PerceptionOptions  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scene", type=Path, default=ROOT / "benchmarks/unseen/panda/pillars.toml")
    parser.add_argument("--turn", type=float, default=60.0, help="second camera's azimuth [deg]")
    parser.add_argument("--noise", type=float, nargs="+", default=[0.5, 1.0, 3.0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3, 4])
    parser.add_argument("--defaults", action="store_true", help="the calibration errors on")
    args = parser.parse_args(argv)
    options = PerceptionOptions(restarts=1) if args.defaults else PerceptionOptions.exact()
    problem = oo.load_scene(args.scene)
    assert problem.object is not None
    configured = camera_of_scene(problem)
    first = DepthCamera(problem, configured)
    away = first.position[:2] - problem.object.pose[:2]
    azimuth = math.degrees(math.atan2(away[1], away[0])) + args.turn
    second = DepthCamera(problem, dataclasses.replace(configured, azimuth=azimuth))
    print(_common.machine_line(_common.machine_info()))
    print(f"{args.scene.name}, second camera at azimuth {azimuth:.0f} deg; {options}")
    print("| noise | seed | u: first, second, fused | error [mm] | sd [mm] |")
    print("|--:|--:|:--|:--|:--|")
    truth = problem.object.pose[:3]
    for noise in args.noise:
        for seed in args.seeds:
            views = [
                perceive(
                    problem,
                    noise=NoiseOptions(scale=noise),
                    depth_camera=camera,
                    rng=np.random.default_rng(seed + 100 * k),
                    options=options,
                )
                for k, camera in enumerate((first, second))
            ]
            fused = fuse(problem, views)
            rows = [(v.u, v.pose, v.pose_covariance) for v in views]
            rows.append((fused.u, fused.pose, fused.pose_covariance))
            us = ", ".join(f"{u:.2f}" for u, _, _ in rows)
            errors = ", ".join(f"{np.linalg.norm(p[:3] - truth) * 1e3:.1f}" for _, p, _ in rows)
            sds = ", ".join(f"{math.sqrt(np.trace(c[:3, :3])) * 1e3:.2f}" for _, _, c in rows)
            print(f"| {noise:g} | {seed} | {us} | {errors} | {sds} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
