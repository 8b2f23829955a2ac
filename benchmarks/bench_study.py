"""Throughput of the study: paired trials per second per worker (one process).

Each trial of ``openup-ompl study`` draws an instance, its belief, then plans and
executes in physics once per distinct ``u`` among the policies (policies that give the
same ``u`` share the run). Here ``--trials`` trials per family run in this one process
(:func:`openup_ompl.study.run.run_trial`, exactly what a task process runs, without the
process start), timed one by one. Reported per family: median and mean seconds per
trial, trials per second, and the runs (plan + rollout) per trial; then the projected
wall time of a study of ``--cells`` cells of ``--per-cell`` trials on ``--workers``
processes (the mean over the families measured, process starts of ~3 s per chunk of 10
trials added).

Run (about 2 min on 2 idle cores)::

    python benchmarks/bench_study.py
    python benchmarks/bench_study.py --families panda-clutter lwa3_sdh-wall --trials 6
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import _common  # noqa: E402

from openup_ompl.study.errors import parse_error  # noqa: E402
from openup_ompl.study.families import parse_families, template_scene  # noqa: E402
from openup_ompl.study.policies import DEFAULT_POLICIES  # noqa: E402
from openup_ompl.study.run import run_trial  # noqa: E402

#: Seconds a task process takes to start and import (measured once by hand: ~3 s).
PROCESS_START = 3.0
CHUNK = 10


def measure(family_name: str, error: str, trials: int, policies: tuple[str, ...]) -> dict:
    family = parse_families([family_name])[0]
    template = template_scene(family)
    source = parse_error(error)
    times, runs = [], []
    with tempfile.TemporaryDirectory() as meshes:
        for i in range(trials):
            started = time.perf_counter()
            record = run_trial(family, template, source, policies, i, seed=7, mesh_dir=Path(meshes))
            times.append(time.perf_counter() - started)
            runs.append(len({r["u"] for r in record["results"].values()}))
            print(f"{family_name} trial {i}: {times[-1]:.2f} s", file=sys.stderr)
    return {
        "family": family_name,
        "median_s": statistics.median(times),
        "mean_s": statistics.fmean(times),
        "runs_per_trial": statistics.fmean(runs),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--families", nargs="+", default=["panda-can", "panda-clutter", "lwa3_sdh-can",
                                          "lwa3_sdh-clutter"],
    )  # fmt: skip
    parser.add_argument("--error", default="pose-1cm")
    parser.add_argument("--trials", type=int, default=5, help="trials per family")
    parser.add_argument("--policies", nargs="+", default=list(DEFAULT_POLICIES))
    parser.add_argument("--cells", type=int, default=32, help="cells of the projected study")
    parser.add_argument("--per-cell", type=int, default=200, help="trials per projected cell")
    parser.add_argument("--workers", type=int, default=2, help="workers of the projection")
    parser.add_argument("--json", default=None, help="write the results as JSON")
    args = parser.parse_args()
    from ompl import util as ompl_util

    ompl_util.setLogLevel(ompl_util.LOG_ERROR)  # as the task processes run
    info = _common.machine_info()
    rows = [measure(f, args.error, args.trials, tuple(args.policies)) for f in args.families]
    mean = statistics.fmean(r["mean_s"] for r in rows)
    total = args.cells * args.per_cell * (mean + PROCESS_START / CHUNK)
    print(_common.machine_line(info))
    print()
    print(f"{args.trials} trials per family, error {args.error}, policies {args.policies}")
    print()
    print(
        _common.markdown_table(
            ["family", "median s/trial", "mean s/trial", "trials/s/worker", "runs/trial"],
            [
                [
                    r["family"],
                    f"{r['median_s']:.2f}",
                    f"{r['mean_s']:.2f}",
                    f"{1 / r['mean_s']:.3f}",
                    f"{r['runs_per_trial']:.1f}",
                ]
                for r in rows
            ],  # fmt: skip
        )
    )
    print()
    print(
        f"Projected: {args.cells} cells x {args.per_cell} trials on {args.workers} workers:"
        f" {total / args.workers / 3600:.1f} h ({mean:.2f} s per trial on average)"
    )
    _common.write_json(
        args.json, {"machine": info, "rows": rows, "projected_hours": total / args.workers / 3600}
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
