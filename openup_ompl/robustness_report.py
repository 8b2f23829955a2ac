"""The robustness sweep's report: its CSV, Markdown tables and success-rate plot.

Formats rows it is given (one per ``(u, dx, dy, yaw)`` cell, as
:func:`openup_ompl.robustness.summarize` makes them); runs nothing.
"""

from __future__ import annotations

import csv
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from openup_ompl.viz._mpl import _pyplot, _save

__all__ = ["markdown_tables", "plot_robustness", "write_csv"]


def _direction(row: dict[str, Any]) -> str:
    if row["dx"] == 0 and row["dy"] == 0:
        return "none"
    axis = "x" if row["dx"] != 0 else "y"
    return ("+" if row["dx"] + row["dy"] > 0 else "-") + axis


def _magnitude(row: dict[str, Any]) -> float:
    return float(abs(row["dx"]) + abs(row["dy"]))


def _grouped(rows: Sequence[dict[str, Any]], by_direction: bool) -> dict[Any, list[int]]:
    """``(u, direction or "all", |delta|) -> [successes, trials]`` (yaws pooled; the zero
    error's direction is ``"none"``)."""
    table: dict[Any, list[int]] = {}
    for row in rows:
        direction = _direction(row) if by_direction else "all"
        cell = table.setdefault((row["u"], direction, _magnitude(row)), [0, 0])
        cell[0] += row["successes"]
        cell[1] += row["trials"]
    return table


def markdown_tables(rows: Sequence[dict[str, Any]]) -> str:
    """Success per ``u`` and error magnitude (directions and yaws pooled), then per
    direction; cells are ``successes/trials``.

    Args:
        rows: The CSV rows of the sweep (``u``, ``dx``, ``dy``, ``yaw``, ``trials``,
            ``successes``, ...).

    Returns:
        The Markdown text of ``robustness.md``.
    """
    us = sorted({row["u"] for row in rows})
    magnitudes = sorted({_magnitude(row) for row in rows})
    head = "| u | " + " | ".join(f"{m * 100:g} cm" for m in magnitudes) + " |"
    rule = "|---:|" + "---:|" * len(magnitudes)
    pooled = _grouped(rows, by_direction=False)
    yaws = sorted({float(row.get("yaw", 0.0)) for row in rows})
    # The tables pool every yaw of a cell (the CSV keeps them apart): say so when several.
    note = "" if len(yaws) < 2 else f"yaws {', '.join(f'{y:g}' for y in yaws)} rad pooled"
    also = f"; {note}" if note else ""
    lines = [f"Success (directions pooled{also}): successes / trials", "", head, rule]
    for u in us:
        cells = [pooled.get((u, "all", m)) for m in magnitudes]
        lines.append(
            f"| {u:g} | " + " | ".join(f"{c[0]}/{c[1]}" if c else "" for c in cells) + " |"
        )
    by_direction = _grouped(rows, by_direction=True)
    directions = [d for d in ("+x", "-x", "+y", "-y") if any(k[1] == d for k in by_direction)]
    if directions:
        moved = [m for m in magnitudes if m > 0]
        lines += [
            "",
            f"Success per direction of the error{f' ({note})' if note else ''}: successes / trials",
            "",
        ]
        lines.append("| u | error | " + " | ".join(f"{m * 100:g} cm" for m in moved) + " |")
        lines.append("|---:|:---|" + "---:|" * len(moved))
        for u in us:
            for d in directions:
                cells = [by_direction.get((u, d, m)) for m in moved]
                lines.append(
                    f"| {u:g} | {d} | "
                    + " | ".join(f"{c[0]}/{c[1]}" if c else "" for c in cells)
                    + " |"
                )
    return "\n".join(lines) + "\n"


def write_csv(
    rows: Sequence[dict[str, Any]], path: Path, columns: Sequence[str] | None = None
) -> Path:
    """``robustness.csv``: ``columns`` (default: the first row's keys, in order), one row
    per cell, ``success_rate`` to four decimals and a physics sweep's ``moved_mm`` to two.

    Args:
        rows: The rows to write.
        path: The CSV file.
        columns: The columns, in order.

    Returns:
        ``path``.
    """
    columns = list(columns if columns is not None else rows[0])
    with path.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=columns)
        writer.writeheader()
        for row in rows:
            moved = row.get("moved_mm")
            extra = {"moved_mm": f"{moved:.2f}"} if isinstance(moved, float) else {}
            writer.writerow({**row, "success_rate": f"{row['success_rate']:.4f}", **extra})
    return path


def plot_robustness(rows: Sequence[dict[str, Any]], path: Path, title: str = "") -> Path:
    """Success rate against the error magnitude, one line per ``u``: all directions
    pooled, then one panel per direction.

    Args:
        rows: The CSV rows of the sweep.
        path: The PNG file to write.
        title: Figure title.

    Returns:
        ``path``.
    """

    plt = _pyplot()
    us = sorted({row["u"] for row in rows})
    grouped = _grouped(rows, by_direction=True)
    pooled = _grouped(rows, by_direction=False)
    panels = ["all", *[d for d in ("+x", "-x", "+y", "-y") if any(k[1] == d for k in grouped)]]
    figure, axes = plt.subplots(
        1, len(panels), figsize=(3.2 * len(panels), 3.4), sharey=True, squeeze=False
    )
    colours = plt.get_cmap("viridis")(np.linspace(0.0, 0.9, len(us)))
    for ax, panel in zip(axes[0], panels, strict=True):
        table = pooled if panel == "all" else grouped
        for u, colour in zip(us, colours, strict=True):
            points = sorted(
                (m * 100, s / t)
                for (uu, name, m), (s, t) in table.items()
                if uu == u and (name == panel or (name == "none" and panel != "all"))
            )
            if points:
                xs, ys = zip(*points, strict=True)
                ax.plot(xs, ys, "o-", color=colour, label=f"u = {u:g}")
        ax.set_title("all directions" if panel == "all" else f"error along {panel}")
        ax.set_xlabel("object pose error [cm]")
        ax.set_ylim(-0.05, 1.05)
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("success rate")
    axes[0][0].legend(loc="lower left", fontsize=8)
    if title:
        figure.suptitle(title)
    figure.tight_layout()
    return _save(figure, path, 120)
