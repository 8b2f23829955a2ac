"""Time per simulated view: ray cast, noise, superquadric fit (openup_ompl.perception).

One scene, one camera (160 x 120 by default); each view draws fresh sensor noise. Reported:
median and 90th percentile ms of the ray cast (``DepthCamera.render``, ``mj_multiRay``),
the noise model and free-space mask (``noisy_cloud``, ``support_under``,
``silhouette_of``), the fit (``fit_superquadric``, weighted, with the silhouette) and
their sum (wall clock), and the sum's CPU time (``time.process_time``: what one core
spends, whatever else the machine runs); object points per view. Set
``OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1`` (as below) to measure one core.

Run (about 15 s on an idle core)::

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python benchmarks/bench_perception.py
    python benchmarks/bench_perception.py --views 200 --width 320 --height 240 --json out.json
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import _common  # noqa: E402

import openup_ompl  # noqa: E402
from openup_ompl.perception import CameraOptions, DepthCamera, NoiseOptions  # noqa: E402
from openup_ompl.perception.fit import fit_superquadric  # noqa: E402
from openup_ompl.perception.noise import noisy_cloud, normal_sigma  # noqa: E402
from openup_ompl.perception.perceive import silhouette_of  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def measure(scene: Path, views: int, width: int, height: int, seed: int) -> dict[str, object]:
    problem = openup_ompl.load_scene(scene)
    options = CameraOptions(width=width, height=height)
    camera = DepthCamera(problem, options)
    noise = NoiseOptions()
    weights = normal_sigma(camera.position, camera.rotation, noise)
    rng = np.random.default_rng(seed)
    times: dict[str, list[float]] = {
        "ray cast": [],
        "noise": [],
        "fit": [],
        "total": [],
        "total cpu": [],
    }
    points = []
    fit_superquadric(noisy_cloud(camera.render(), noise, rng).points)  # warm up scipy
    for _ in range(views):
        c0, t0 = time.process_time(), time.perf_counter()
        view = camera.render()
        t1 = time.perf_counter()
        cloud = noisy_cloud(view, noise, rng)
        silhouette = silhouette_of(view, noise, options, camera.support_under(cloud.points))
        t2 = time.perf_counter()
        fit_superquadric(cloud.points, None, silhouette, weights)
        t3, c3 = time.perf_counter(), time.process_time()
        spans = (t1 - t0, t2 - t1, t3 - t2, t3 - t0, c3 - c0)
        for key, value in zip(times, spans, strict=True):
            times[key].append(value * 1e3)
        points.append(cloud.points.shape[0])
    return {
        "scene": scene.name,
        "resolution": f"{width}x{height}",
        "views": views,
        "points": float(np.median(points)),
        **{f"{k} median ms": _common.median(v) for k, v in times.items()},
        **{f"{k} p90 ms": _common.percentile(v, 90) for k, v in times.items()},
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--scene",
        type=Path,
        default=ROOT / "scenes" / "lwa3_sdh_can.toml",
        help="scene TOML (default: the demo's, scenes/lwa3_sdh_can.toml)",
    )
    parser.add_argument("--views", type=int, default=50, help="views (default 50)")
    parser.add_argument("--width", type=int, default=160, help="image width [px] (160)")
    parser.add_argument("--height", type=int, default=120, help="image height [px] (120)")
    parser.add_argument("--seed", type=int, default=1, help="noise seed (1)")
    parser.add_argument("--json", type=Path, default=None, help="also write the row as JSON")
    args = parser.parse_args()
    row = measure(args.scene, args.views, args.width, args.height, args.seed)
    print(_common.machine_line(_common.machine_info()))
    print()
    print(
        _common.markdown_table(
            ["quantity", "value"],
            [
                [key, f"{value:.2f}" if isinstance(value, float) else value]
                for key, value in row.items()
            ],
        )
    )
    if args.json is not None:
        _common.write_json(str(args.json), {"machine": _common.machine_info(), "rows": [row]})


if __name__ == "__main__":
    main()
