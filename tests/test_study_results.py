"""The committed study tables: every interval and p-value recomputes from its counts."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from openup_ompl.study.stats import mcnemar_exact, wilson_interval

RESULTS = Path(__file__).resolve().parent.parent / "docs" / "results"
MAPS = sorted(RESULTS.rglob("uncertainty_map.csv"))


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as handle:
        return list(csv.DictReader(handle))


def test_the_committed_study_tables_are_there() -> None:
    """The committed run, its replication and the held-out run each have their tables."""
    names = {p.parent.relative_to(RESULTS).as_posix() for p in MAPS}
    assert {".", "study_lwa3_sdh", "study_seed1/panda", "study_seed3/panda"} <= names
    assert all((p.parent / "uncertainty_pairs.csv").exists() for p in MAPS)


@pytest.mark.parametrize("path", MAPS, ids=lambda p: p.parent.relative_to(RESULTS).as_posix())
def test_rates_and_wilson_intervals_recompute_from_the_counts(path: Path) -> None:
    """Each row's rate and Wilson 95 % interval follow from its trials and successes, and
    the pooled rows add up the families' counts."""
    rows = _rows(path)
    for row in rows:
        trials, successes = int(row["trials"]), int(row["successes"])
        low, high = wilson_interval(successes, trials)
        assert float(row["rate"]) == pytest.approx(successes / trials, abs=1e-6)
        assert (float(row["ci_low"]), float(row["ci_high"])) == pytest.approx((low, high), abs=1e-6)
    for pooled in (r for r in rows if r["family"] == "all" and r["error"] != "all"):
        cells = [
            r
            for r in rows
            if r["family"] != "all" and r["error"] == pooled["error"]
            and r["policy"] == pooled["policy"]
        ]  # fmt: skip
        assert int(pooled["trials"]) == sum(int(r["trials"]) for r in cells)
        assert int(pooled["successes"]) == sum(int(r["successes"]) for r in cells)


@pytest.mark.parametrize("path", MAPS, ids=lambda p: p.parent.relative_to(RESULTS).as_posix())
def test_mcnemar_p_values_recompute_from_the_discordant_counts(path: Path) -> None:
    """Each pair's exact McNemar p is the two-sided binomial test of its discordant
    counts, and the discordant counts fit in the paired trials."""
    for row in _rows(path.parent / "uncertainty_pairs.csv"):
        a_only, b_only = int(row["a_only"]), int(row["b_only"])
        assert a_only + b_only <= int(row["n"])
        assert float(row["p_value"]) == pytest.approx(mcnemar_exact(a_only, b_only), rel=1e-5)
