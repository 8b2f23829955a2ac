"""What re-validating a plan costs ``openup-ompl execute``, beside the execution itself.

For every shipped robot's can scene (``scenes/<robot>_can.toml``) and N seeds: plan, save,
then time, side by side on the same plan file, reading it and re-validating it against its
scene (``revalidate_plan``: limits, the hand on the law, step sizes, every motion by the
certified check) and executing it in physics (``execute_plan``, no frames). The ratio of
the medians is what the re-validation adds to an execution.

Run (about a minute with the defaults on 2 cores)::

    python benchmarks/bench_revalidate.py
    python benchmarks/bench_revalidate.py --seeds 5 --json bench_revalidate.json
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import _common  # noqa: E402

import openup_ompl  # noqa: E402
from openup_ompl._resources import data_dir  # noqa: E402
from openup_ompl.physics import execute_plan  # noqa: E402
from openup_ompl.plan import PlanFile  # noqa: E402
from openup_ompl.revalidate import revalidate_plan  # noqa: E402


def main() -> None:
    """Plan, re-validate and execute each scene's plans; print the table."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, default=3, help="plans per scene (seeds 1..N)")
    parser.add_argument("--json", default=None, help="write the results to this JSON file")
    args = parser.parse_args()
    info = _common.machine_info()
    rows, results = [], {}
    with tempfile.TemporaryDirectory() as tmp:
        for robot in openup_ompl.available_robots():
            scene = data_dir("scenes") / f"{robot}_can.toml"
            if not scene.is_file():
                continue
            setup = openup_ompl.GraspPlanningSetup(openup_ompl.load_scene(scene))
            checks, runs, states = [], [], []
            for seed in range(1, args.seeds + 1):
                path = setup.solve(seed=seed).save(Path(tmp) / f"{robot}-{seed}.json")
                start = time.perf_counter()
                states.append(revalidate_plan(PlanFile.read(path)).states)
                checks.append(time.perf_counter() - start)
                start = time.perf_counter()
                execute_plan(path, frames=False)
                runs.append(time.perf_counter() - start)
            check, run = _common.median(checks), _common.median(runs)
            results[scene.stem] = {"states": states, "revalidate_s": checks, "execute_s": runs}
            rows.append(
                (
                    scene.stem,
                    args.seeds,
                    f"{min(states)}-{max(states)}",
                    f"{check:.2f}",
                    f"{run:.2f}",
                    f"{check / run:.2f}",
                )
            )
    header = ("scene", "plans", "rows", "re-validation [s]", "execution [s]", "ratio")
    print(_common.markdown_table(header, rows))
    print(f"\nmedians over the plans; {_common.machine_line(info)}")
    _common.write_json(args.json, {"machine": info, "seeds": args.seeds, "scenes": results})


if __name__ == "__main__":
    main()
