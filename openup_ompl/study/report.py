"""The study's outputs: ``uncertainty_map.csv``, ``uncertainty_pairs.csv`` and the figure.

``uncertainty_map.csv``, one row per ``(family, error, policy)`` cell (:data:`MAP_COLUMNS`):
trials, trials held (``successes``), the rate and its Wilson 95 % interval, trials where
a neighbour was disturbed (moved > 2 cm or tipped; ``NA`` when the rollout does not
report it) and those held with no neighbour disturbed, trials where the robot touched a
movable neighbour, plan failures, views perception refused (``not_seen``), trials where
a robot link touched a fixed obstacle and the mean ``u`` of the planned trials.

``uncertainty_pairs.csv``, one row per cell and pair of policies (:data:`PAIR_COLUMNS`):
the paired trials ``n``, those only A held and only B held, and the exact McNemar test's
two-sided p-value (:func:`~openup_ompl.study.stats.mcnemar_exact`).

Both add pooled rows (family ``all``: every family per error; family and error ``all``:
everything) when the study has more than one family.
"""

from __future__ import annotations

import csv
from collections.abc import Sequence
from itertools import combinations
from pathlib import Path
from typing import Any

import numpy as np

from openup_ompl._io import make_dir
from openup_ompl.study.stats import mcnemar_exact, wilson_interval

__all__ = [
    "MAP_COLUMNS",
    "PAIR_COLUMNS",
    "POOLED",
    "map_rows",
    "pair_rows",
    "plot_study",
    "write_rows",
]

MAP_COLUMNS = (
    "family", "error", "policy", "trials", "successes", "rate", "ci_low", "ci_high",
    "disturbed", "held_undisturbed", "neighbour_touched", "plan_failures", "not_seen",
    "obstacle_contacts", "mean_u",
)  # fmt: skip
PAIR_COLUMNS = ("family", "error", "policy_a", "policy_b", "n", "a_only", "b_only", "p_value")


#: The family and error names of pooled rows.
POOLED = "all"


def _cells(records: Sequence[dict[str, Any]]) -> dict[tuple[str, str], list[dict[str, Any]]]:
    """The trials of each ``(family, error)``, in trial order; then, with more than one
    family, every family pooled per error (family :data:`POOLED`), and with more than one
    error as well, everything pooled (``(POOLED, POOLED)``). Pooled trials stay paired:
    each is one trial of every policy."""
    cells: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for record in records:
        cells.setdefault((record["family"], record["error"]), []).extend(record["trials"])
    ordered = {key: sorted(trials, key=lambda t: t["trial"]) for key, trials in cells.items()}
    families = {family for family, _ in ordered}
    errors = list(dict.fromkeys(error for _, error in ordered))
    if len(families) > 1:
        for error in errors:
            ordered[(POOLED, error)] = [t for (_, e), ts in cells.items() if e == error for t in ts]
        if len(errors) > 1:
            ordered[(POOLED, POOLED)] = [t for ts in cells.values() for t in ts]
    return ordered


def map_rows(records: Sequence[dict[str, Any]], policies: Sequence[str]) -> list[dict[str, Any]]:
    """Success rates per cell, with their Wilson 95 % intervals.

    Args:
        records: The trials' records (one per trial).
        policies: The policies, canonical names.

    Returns:
        One :data:`MAP_COLUMNS` row per ``(family, error, policy)``, pooled cells included.
    """
    rows = []
    for (family, error), trials in _cells(records).items():
        for policy in policies:
            results = [t["results"][policy] for t in trials if policy in t["results"]]
            held = sum(bool(r["held"]) for r in results)
            low, high = wilson_interval(held, len(results))
            known = [r.get("disturbed") for r in results if r.get("disturbed") is not None]
            us = [r["u"] for r in results if r.get("planned") and r.get("u") is not None]
            rows.append(
                {
                    "family": family,
                    "error": error,
                    "policy": policy,
                    "trials": len(results),
                    "successes": held,
                    "rate": held / len(results) if results else 0.0,
                    "ci_low": low,
                    "ci_high": high,
                    "disturbed": sum(bool(d) for d in known) if known else "NA",
                    "held_undisturbed": sum(
                        bool(r["held"]) and r.get("disturbed") is False for r in results
                    )
                    if known
                    else "NA",
                    "neighbour_touched": sum(bool(r.get("neighbour_touched")) for r in results),
                    "plan_failures": sum(r["cause"] == "plan failed" for r in results),
                    "not_seen": sum(r["cause"] == "not seen" for r in results),
                    "obstacle_contacts": sum(bool(r.get("obstacle_contact")) for r in results),
                    "mean_u": float(np.mean(us)) if us else "",
                }
            )
    return rows


def pair_rows(records: Sequence[dict[str, Any]], policies: Sequence[str]) -> list[dict[str, Any]]:
    """Paired comparisons of the policies, exact McNemar tests on the discordant trials.

    Args:
        records: The trials' records (one per trial).
        policies: The policies, canonical names.

    Returns:
        One :data:`PAIR_COLUMNS` row per ``(family, error)`` and pair of policies.
    """
    rows = []
    for (family, error), trials in _cells(records).items():
        for a, b in combinations(policies, 2):
            both = [t["results"] for t in trials if a in t["results"] and b in t["results"]]
            a_only = sum(bool(r[a]["held"]) and not r[b]["held"] for r in both)
            b_only = sum(bool(r[b]["held"]) and not r[a]["held"] for r in both)
            rows.append(
                {
                    "family": family,
                    "error": error,
                    "policy_a": a,
                    "policy_b": b,
                    "n": len(both),
                    "a_only": a_only,
                    "b_only": b_only,
                    "p_value": mcnemar_exact(a_only, b_only),
                }
            )
    return rows


def _text(value: Any) -> Any:
    return f"{value:.6g}" if isinstance(value, float) else value


def write_rows(rows: Sequence[dict[str, Any]], columns: Sequence[str], path: Path) -> Path:
    """Write a CSV of ``columns`` (floats to six significant digits).

    Args:
        rows: The rows, each holding every column.
        columns: The columns, in order.
        path: The file (its directory is created if missing).

    Returns:
        ``path``.
    """
    make_dir(path.parent)
    with path.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(columns))
        writer.writeheader()
        for row in rows:
            writer.writerow({c: _text(row[c]) for c in columns})
    return path


def plot_study(
    rows: Sequence[dict[str, Any]], errors: Sequence[str], path: Path, title: str = ""
) -> Path:
    """Success rate against the error source, one panel per family, one line per policy
    with its Wilson 95 % band; the trial count in each panel's title.

    Args:
        rows: :func:`map_rows`'s rows.
        errors: The error sources, in x order.
        path: The PNG file.
        title: The figure's title (none if empty).

    Returns:
        The path written.

    Raises:
        MissingExtra: matplotlib is not installed.
    """
    from openup_ompl.viz._mpl import _pyplot, _save

    plt = _pyplot()
    families = list(dict.fromkeys(r["family"] for r in rows if r["error"] != POOLED))
    policies = list(dict.fromkeys(r["policy"] for r in rows))
    columns = min(4, len(families))
    lines = -(-len(families) // columns)
    figure, axes = plt.subplots(
        lines, columns, figsize=(3.4 * columns, 3.0 * lines + 0.6), sharey=True, squeeze=False
    )
    colours = plt.get_cmap("tab10")(np.arange(len(policies)) % 10)
    xs = np.arange(len(errors))
    # Policies that pick the same u draw the same line: each is shifted a little along x,
    # the named ones dashed.
    shifts = (np.arange(len(policies)) - (len(policies) - 1) / 2) * 0.02
    for ax, family in zip(axes.flat, families, strict=False):
        cell = {(r["error"], r["policy"]): r for r in rows if r["family"] == family}
        for policy, colour, shift in zip(policies, colours, shifts, strict=True):
            points = [(i, cell[(e, policy)]) for i, e in enumerate(errors) if (e, policy) in cell]
            if not points:
                continue
            at = np.array([i for i, _ in points]) + shift
            style = "o-" if policy[0].isdigit() else "s--"
            ax.plot(at, [r["rate"] for _, r in points], style, color=colour, label=policy, ms=3)
            low = [r["ci_low"] for _, r in points]
            ax.fill_between(at, low, [r["ci_high"] for _, r in points], color=colour, alpha=0.12)
        trials = max((r["trials"] for r in cell.values()), default=0)
        ax.set_title(f"{family} (n = {trials})", fontsize=9)
        ax.set_xticks(xs, list(errors), rotation=30, fontsize=7)
        ax.set_ylim(-0.05, 1.05)
        ax.grid(alpha=0.3)
    for ax in axes.flat[len(families) :]:
        ax.axis("off")
    for ax in axes[:, 0]:
        ax.set_ylabel("held")
    axes.flat[0].legend(fontsize=6, loc="lower left")
    if title:
        figure.suptitle(title, fontsize=9)
    figure.tight_layout()
    return _save(figure, path, dpi=120)
