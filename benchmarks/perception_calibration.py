"""Calibration of the perceived covariance: the share of views whose true object position
lies inside the reported 95 % region, per shape (cylinder, box, sphere, stick, mesh) and
sensor noise, with its Wilson 95 % interval; and the expected-against-observed coverage
plot at levels 50-99 % (``openup_ompl.perception.calibration``).

    python benchmarks/perception_calibration.py --out docs/results    # about 6 min, 1 core
    python benchmarks/perception_calibration.py --views 10 --noise 1   # a quick look
    python benchmarks/perception_calibration.py --exact                # sensor noise alone

Writes ``perception_calibration.csv`` and ``perception_calibration.png`` into ``--out``
and prints the markdown table. One fit per view (the covariance's calibration, not the
bootstrap median's); the camera's calibration errors at their defaults unless
``--exact``.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import _common  # noqa: E402

from openup_ompl.perception.calibration import (  # noqa: E402
    CALIBRATION_SHAPES,
    coverage_table,
    wilson_interval,
)
from openup_ompl.perception.extrinsic import PerceptionOptions  # noqa: E402

LEVELS = (0.5, 0.8, 0.9, 0.95, 0.99)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--shapes", nargs="+", default=list(CALIBRATION_SHAPES))
    parser.add_argument("--noise", type=float, nargs="+", default=[0.5, 1.0, 2.0, 4.0])
    parser.add_argument("--views", type=int, default=40, help="views per cell (default 40)")
    parser.add_argument("--seed", type=int, default=3000, help="seed of view 0")
    parser.add_argument("--exact", action="store_true", help="no camera calibration errors")
    parser.add_argument("--out", type=Path, default=None, help="folder for the CSV and plot")
    args = parser.parse_args(argv)
    options = PerceptionOptions.exact() if args.exact else PerceptionOptions()
    options = dataclasses.replace(options, restarts=1)
    print(_common.machine_line(_common.machine_info()))
    print(f"error model: {options}")
    start = time.perf_counter()
    table = coverage_table(args.shapes, args.noise, args.views, args.seed, options)
    seconds = time.perf_counter() - start
    rows = []
    for name, noise, cell in table:
        row = {"shape": name, "noise": noise, **cell.row()}
        row.update({f"inside_{round(level * 100)}": cell.inside(level) for level in LEVELS})
        rows.append(row)
    header = (
        "| shape | noise | views (fitted) | inside 95 % [Wilson 95 %] | mean error [mm] |"
        " max error [mm] | mean u |"
    )
    print(header)
    print("|:--|--:|--:|:--|--:|--:|--:|")
    for row in rows:
        print(
            f"| {row['shape']} | {row['noise']:g} | {row['views']} ({row['fitted']}) |"
            f" {row['inside_95']:.0%} [{row['ci_low']:.0%}, {row['ci_high']:.0%}] |"
            f" {row['mean_error_mm']:.1f} | {row['max_error_mm']:.1f} | {row['mean_u']:.3f} |"
        )
    for name in args.shapes:
        cells = [cell for shape, _, cell in table if shape == name]
        hits = sum(int(np.count_nonzero(cell.d2 <= 7.815)) for cell in cells)
        fitted = sum(int(cell.d2.size) for cell in cells)
        low, high = wilson_interval(hits, fitted)
        print(f"{name}: {hits}/{fitted} inside 95 % ({hits / fitted:.1%}, [{low:.1%}, {high:.1%}])")
    hits = sum(int(np.count_nonzero(cell.d2 <= 7.815)) for _, _, cell in table)
    fitted = sum(int(cell.d2.size) for _, _, cell in table)
    low, high = wilson_interval(hits, fitted)
    print(f"pooled: {hits}/{fitted} inside 95 % ({hits / fitted:.1%}, [{low:.1%}, {high:.1%}])")
    print(f"{seconds:.0f} s")
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        suffix = "_exact" if args.exact else ""
        with (args.out / f"perception_calibration{suffix}.csv").open("w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
        _plot(table, args.out / f"perception_calibration{suffix}.png", args.exact)
    return 0


def _plot(table: list, out: Path, exact: bool) -> None:  # type: ignore[type-arg]
    """Expected against observed coverage per shape, pooled over the noise levels."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from scipy.stats import chi2

    levels = np.linspace(0.05, 0.99, 40)
    fig, ax = plt.subplots(figsize=(5.5, 5))
    ax.plot([0, 1], [0, 1], "k--", lw=0.8, label="calibrated")
    for name in dict.fromkeys(shape for shape, _, _ in table):
        d2 = np.concatenate([cell.d2 for shape, _, cell in table if shape == name])
        observed = [float(np.mean(d2 <= chi2.ppf(level, 3))) for level in levels]
        ax.plot(levels, observed, label=f"{name} ({d2.size} views)")
    ax.set_xlabel("expected coverage (reported region's probability)")
    ax.set_ylabel("observed coverage (true position inside)")
    errors = "sensor noise alone" if exact else "with camera calibration errors"
    ax.set_title(f"Perceived covariance: coverage\n({errors}; noise levels pooled)")
    ax.legend(fontsize=8)
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
