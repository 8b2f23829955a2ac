"""A benchmark's report: the per-problem summary of its runs, the Markdown table and the
plots of solve time and success (matplotlib, the ``viz`` extra)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from openup_ompl.viz._mpl import _pyplot, _save

__all__ = ["markdown_table", "plot_results", "summarize"]


def summarize(records: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per (problem, planner, hand): runs, success, median and 95th-percentile solve time
    (a failed run counts as its time), mean path length and counters of the solved runs
    (``None`` when no run was solved).

    Args:
        records: The runs' records.

    Returns:
        One row per (problem, planner, hand), as in ``summary.json``; times in s.
    """
    groups: dict[tuple[str, str, str], list[dict[str, Any]]] = {}
    for record in records:
        key = (record["problem"], record["planner"], record["hand"])
        groups.setdefault(key, []).append(record)
    rows = []
    for (problem, planner, hand), group in groups.items():
        times = np.array([float(r["time"]) for r in group])
        solved = [r for r in group if r["solved"]]

        def mean(field: str, rows: list[dict[str, Any]] = solved) -> float | None:
            values = [float(r[field]) for r in rows if r.get(field) is not None]
            return float(np.mean(values)) if values else None

        rows.append(
            {
                "problem": problem,
                "planner": planner,
                "hand": hand,
                "runs": len(group),
                "success": len(solved) / len(group),
                "median_time": float(np.median(times)),
                "p95_time": float(np.percentile(times, 95)),
                "length": mean("length"),
                "state_checks": mean("state_checks"),
                "ik_calls": mean("ik_calls"),
                "final_aperture": mean("final_aperture"),
            }
        )
    return rows


def plot_results(rows: Sequence[dict[str, Any]], out: Path) -> list[Path]:
    """``solve_time.png`` (median bars, 95th-percentile whiskers, log scale) and
    ``success.png`` per problem and planner configuration.

    Args:
        rows: The summary rows (:func:`summarize`).
        out: The output directory.

    Returns:
        The PNG paths written.

    Raises:
        MissingExtra: matplotlib is not installed.
    """

    plt = _pyplot()
    problems = sorted({r["problem"] for r in rows})
    configs = sorted({(r["planner"], r["hand"]) for r in rows})
    index = {(r["problem"], r["planner"], r["hand"]): r for r in rows}
    width = 0.8 / max(1, len(configs))
    written = []
    for name, field, ylabel in (
        ("solve_time.png", "median_time", "solve time [s] (median; bar to 95th pct)"),
        ("success.png", "success", "success rate"),
    ):
        fig, ax = plt.subplots(figsize=(max(6.0, 1.3 * len(problems)), 4.0))
        for j, (planner, hand) in enumerate(configs):
            xs, ys, errs = [], [], []
            for i, problem in enumerate(problems):
                row = index.get((problem, planner, hand))
                if row is None:
                    continue
                xs.append(i + (j - (len(configs) - 1) / 2) * width)
                ys.append(row[field])
                errs.append(max(0.0, row["p95_time"] - row["median_time"]))
            label = planner if hand == "law" else f"{planner} (fixed w)"
            if field == "median_time":
                ax.bar(xs, ys, width, yerr=[[0] * len(errs), errs], label=label, capsize=2)
                ax.set_yscale("log")
            else:
                ax.bar(xs, ys, width, label=label)
                ax.set_ylim(0, 1.05)
        ax.set_xticks(range(len(problems)), problems, rotation=30, ha="right")
        ax.set_ylabel(ylabel)
        ax.legend(fontsize="small")
        fig.tight_layout()
        written.append(_save(fig, Path(out) / name, 120))
    return written


def markdown_table(rows: Sequence[dict[str, Any]]) -> str:
    """The results table (times in ms).

    Args:
        rows: :func:`summarize`'s rows: ``success`` a rate in ``[0, 1]``, ``median_time``
            and ``p95_time`` [s], ``length`` the mean path length [rad] (``None``: no run
            solved).

    Returns:
        The table in Markdown, success in percent, times in ms.
    """
    lines = [
        "| problem | planner | hand | runs | success | median [ms] | p95 [ms] | length [rad] |",
        "|:--|:--|:--|--:|--:|--:|--:|--:|",
    ]
    for r in rows:
        length = "-" if r["length"] is None else f"{r['length']:.2f}"
        lines.append(
            f"| {r['problem']} | {r['planner']} | {r['hand']} | {r['runs']} | "
            f"{100 * r['success']:.0f} % | {1e3 * r['median_time']:.0f} | "
            f"{1e3 * r['p95_time']:.0f} | {length} |"
        )
    return "\n".join(lines)
