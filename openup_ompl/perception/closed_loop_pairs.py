"""The closed loop's policies compared on the same views: every policy against a reference,
per (noise, distance) cell and pooled, with the exact McNemar test.

All policies of a closed-loop trial share its view (:mod:`openup_ompl.perception.closed_loop`),
so two policies' verdicts on a view are a pair; only the views where one policy held and
the other did not (the discordant pairs) carry information about which is better.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from openup_ompl.exceptions import ConfigError
from openup_ompl.study.stats import mcnemar_exact

__all__ = ["PAIR_COLUMNS", "POOLED", "compare_policies", "default_reference", "write_pairs_csv"]

#: The columns of ``closed_loop_pairs.csv``.
PAIR_COLUMNS = (
    "policy",
    "reference",
    "noise",
    "distance",
    "views",
    "policy_successes",
    "reference_successes",
    "policy_only",
    "reference_only",
    "p_value",
)
#: The ``noise`` and ``distance`` of the row pooled over every cell.
POOLED = "all"


def default_reference(policies: Sequence[str]) -> str:
    """The policy the others are compared with: ``"covariance"`` when it ran, else the first.

    Args:
        policies: The run's policies, in order.

    Returns:
        The reference policy's name.

    Raises:
        ConfigError: No policy.
    """
    if not policies:
        raise ConfigError("policies", list(policies), "at least one policy")
    return "covariance" if "covariance" in policies else str(policies[0])


def compare_policies(
    records: Sequence[dict[str, Any]], reference: str = "covariance"
) -> list[dict[str, Any]]:
    """Every other policy against ``reference`` on the views both were judged on.

    Args:
        records: The trials' records (:func:`~openup_ompl.perception.closed_loop.closed_loop`,
            or ``closed_loop_trials.json``): ``policy``, ``noise``, ``distance`` [m],
            ``seed``, ``success``.
        reference: The policy the others are compared with.

    Returns:
        Rows with the :data:`PAIR_COLUMNS`, per cell in the records' order and then pooled
        (``noise`` and ``distance`` :data:`POOLED`); ``p_value`` is the exact McNemar
        test's two-sided p on the discordant views (1 without any).

    Raises:
        ConfigError: ``reference`` is not among the records' policies.
    """
    verdicts: dict[tuple[Any, Any, Any], dict[str, bool]] = {}
    for record in records:
        view = (record["noise"], record["distance"], record["seed"])
        verdicts.setdefault(view, {})[str(record["policy"])] = bool(record["success"])
    policies = list(dict.fromkeys(str(record["policy"]) for record in records))
    if reference not in policies:
        raise ConfigError("reference", reference, f"one of the run's policies {policies}")
    cells = list(dict.fromkeys((noise, distance) for noise, distance, _ in verdicts))
    rows = []
    for policy in (p for p in policies if p != reference):
        for cell in [*cells, None]:
            pairs = [
                (by_policy[policy], by_policy[reference])
                for view, by_policy in verdicts.items()
                if (cell is None or view[:2] == cell)
                and policy in by_policy
                and reference in by_policy
            ]
            policy_only = sum(mine and not theirs for mine, theirs in pairs)
            reference_only = sum(theirs and not mine for mine, theirs in pairs)
            rows.append(
                {
                    "policy": policy,
                    "reference": reference,
                    "noise": POOLED if cell is None else cell[0],
                    "distance": POOLED if cell is None else cell[1],
                    "views": len(pairs),
                    "policy_successes": sum(mine for mine, _ in pairs),
                    "reference_successes": sum(theirs for _, theirs in pairs),
                    "policy_only": policy_only,
                    "reference_only": reference_only,
                    "p_value": mcnemar_exact(policy_only, reference_only),
                }
            )
    return rows


def write_pairs_csv(rows: Sequence[dict[str, Any]], path: Path) -> Path:
    """Write :func:`compare_policies`' rows (p to four significant digits).

    Args:
        rows: The comparisons.
        path: The CSV file to write (its directory is created).

    Returns:
        ``path``.
    """
    from openup_ompl.study.report import write_rows

    # The cells' noise and distance as the per-cell table writes them (1.0, not 1).
    text = [
        {
            **row,
            "noise": str(row["noise"]),
            "distance": str(row["distance"]),
            "p_value": f"{row['p_value']:.4g}",
        }
        for row in rows
    ]
    return write_rows(text, PAIR_COLUMNS, path)
