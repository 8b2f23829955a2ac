"""`perceive` with its defaults on every scene the project ships: it either estimates the
object or says in one line why no view can see it.

For every scene file with an ``[object]`` under ``scenes/`` and ``benchmarks/`` (all three
robots), one view per seed with the defaults of ``openup-ompl perceive`` (``--camera auto``,
the Kinect-like noise, the camera's calibration errors, five fits): the view used, the
position error [mm], the largest standard deviation of the position [mm] and ``u``; or the
refusal (its exception and message, which must be one line). The last line states the
check: every scene estimated or refused in one line.

Run::

    python benchmarks/perception_every_scene.py                 # seeds 1-3
    python benchmarks/perception_every_scene.py --seeds 1 --exact
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from openup_ompl.exceptions import PerceptionError
from openup_ompl.perception import perceive
from openup_ompl.perception.extrinsic import PerceptionOptions
from openup_ompl.scene import load_scene

ROOT = Path(__file__).resolve().parents[1]


def scene_files(only: str = "") -> list[Path]:
    """Every shipped scene file that has an object to perceive (whose path holds ``only``)."""
    files = sorted((ROOT / "scenes").glob("*.toml")) + sorted((ROOT / "benchmarks").rglob("*.toml"))
    return [f for f in files if "\n[object]" in "\n" + f.read_text() and only in str(f)]


def look(path: Path, seed: int, options: PerceptionOptions) -> dict[str, object]:
    """One view of the scene's object with the defaults; its figures or its refusal."""
    problem = load_scene(path)
    assert problem.object is not None
    started = time.perf_counter()
    try:
        seen = perceive(problem, "auto", rng=np.random.default_rng(seed), options=options)
    except PerceptionError as refusal:
        message = str(refusal)
        one_line = "\n" not in message.strip()
        return {"refused": type(refusal).__name__, "message": message,
                "one_line": one_line, "s": time.perf_counter() - started}  # fmt: skip
    error = np.linalg.norm(seen.pose[:3] - problem.object.pose[:3]) * 1e3
    sigma = np.sqrt(np.max(np.linalg.eigvalsh(seen.position_covariance))) * 1e3
    return {"error_mm": float(error), "sigma_mm": float(sigma), "u": float(seen.u),
            "s": time.perf_counter() - started}  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=3, help="views per scene (seeds 1..N)")
    parser.add_argument("--exact", action="store_true", help="the sensor noise alone")
    parser.add_argument("--only", default="", help="only the scene files whose path holds this")
    args = parser.parse_args()
    options = PerceptionOptions.exact() if args.exact else PerceptionOptions()
    print("| scene | seed | result | position error [mm] | largest sigma [mm] | u | time [s] |")
    print("|:--|--:|:--|--:|--:|--:|--:|")
    failures, errors = [], []
    files = scene_files(args.only)
    for path in files:
        name = path.relative_to(ROOT)
        for seed in range(1, args.seeds + 1):
            row = look(path, seed, options)
            if "refused" in row:
                refusal = f"{row['refused']}: {row['message']}"
                print(f"| `{name}` | {seed} | {refusal} | | | | {row['s']:.1f} |")
                if not row["one_line"]:
                    failures.append(f"{name} seed {seed}: a refusal of several lines")
            else:
                errors.append(row["error_mm"])
                print(f"| `{name}` | {seed} | estimated | {row['error_mm']:.1f} |"
                      f" {row['sigma_mm']:.1f} | {row['u']:.2f} | {row['s']:.1f} |")  # fmt: skip
            sys.stdout.flush()
    views = len(files) * args.seeds
    print(f"\n{len(errors)} of {views} views estimated (position error median"
          f" {np.median(errors):.1f} mm, largest {max(errors):.1f} mm), {views - len(errors)}"
          f" refused; every scene estimated or refused in one line: {not failures}")  # fmt: skip
    for failure in failures:
        print(f"  {failure}")


if __name__ == "__main__":
    main()
