"""The closed loop's paired comparisons and the Wilson intervals of its table."""

from __future__ import annotations

import csv

import pytest

from openup_ompl.exceptions import ConfigError
from openup_ompl.perception.closed_loop import summarize
from openup_ompl.perception.closed_loop_pairs import (
    POOLED,
    compare_policies,
    default_reference,
    write_pairs_csv,
)
from openup_ompl.study.stats import mcnemar_exact, wilson_interval


def _records(verdicts: dict[tuple[float, int], dict[str, bool]]) -> list[dict]:
    """Closed-loop records from {(noise, seed): {policy: success}} at one distance."""
    return [
        {
            "noise": noise,
            "distance": 0.6,
            "seed": seed,
            "policy": policy,
            "success": ok,
            "u": 0.0,
            "error_mm": 1.0,
            "seen": True,
            "planned": True,
        }  # fmt: skip
        for (noise, seed), by_policy in verdicts.items()
        for policy, ok in by_policy.items()
    ]


VERDICTS = {
    (1.0, 1): {"0": True, "covariance": True},
    (1.0, 2): {"0": False, "covariance": True},
    (1.0, 3): {"0": False, "covariance": True},
    (2.0, 1): {"0": True, "covariance": False},
    (2.0, 2): {"0": False, "covariance": False},
}


def test_pairs_count_the_discordant_views_per_cell_and_pooled():
    """Per cell and pooled, the discordant views are counted each way and the p-value is
    the exact McNemar test's on them."""
    rows = compare_policies(_records(VERDICTS), "covariance")
    by_noise = {row["noise"]: row for row in rows}
    assert set(by_noise) == {1.0, 2.0, POOLED}
    assert (by_noise[1.0]["policy_only"], by_noise[1.0]["reference_only"]) == (0, 2)
    assert (by_noise[2.0]["policy_only"], by_noise[2.0]["reference_only"]) == (1, 0)
    pooled = by_noise[POOLED]
    assert pooled["views"] == 5
    assert (pooled["policy_successes"], pooled["reference_successes"]) == (2, 3)
    assert pooled["p_value"] == pytest.approx(mcnemar_exact(1, 2))


def test_pairs_skip_a_view_one_policy_did_not_finish():
    """A view judged for one policy only (an interrupted run) is not a pair."""
    verdicts = {**VERDICTS, (2.0, 3): {"0": True}}
    pooled = [r for r in compare_policies(_records(verdicts)) if r["noise"] == POOLED]
    assert pooled[0]["views"] == 5 and pooled[0]["policy_successes"] == 2


def test_the_reference_must_have_run():
    """A reference policy the run did not have is refused, naming it."""
    with pytest.raises(ConfigError, match="'adaptive'"):
        compare_policies(_records(VERDICTS), "adaptive")
    assert default_reference(["0", "0.3"]) == "0"
    assert default_reference(["0", "covariance"]) == "covariance"
    with pytest.raises(ConfigError, match="policies"):
        default_reference([])


def test_the_table_carries_each_rates_wilson_interval(tmp_path):
    """Every row's interval is the Wilson interval of its own count, and the pairs CSV
    keeps the counts it was computed from."""
    records = _records(VERDICTS)
    for row in summarize(records):
        assert (row["ci_low"], row["ci_high"]) == pytest.approx(
            wilson_interval(row["successes"], row["trials"])
        )
        assert row["ci_low"] <= row["success_rate"] <= row["ci_high"]
    path = write_pairs_csv(compare_policies(records), tmp_path / "pairs.csv")
    with path.open(newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert [r["noise"] for r in rows] == ["1.0", "2.0", POOLED]
    assert rows[-1]["policy_only"] == "1" and rows[-1]["reference_only"] == "2"


def test_a_views_plans_depend_on_its_seed_alone() -> None:
    """A view's plans depend on its seed and u only: a policy plans the same path whether or
    not another was planned before it, and a run that starts at a later seed plans that
    seed's view as a run through it does (runs of seed ranges side by side join into one
    experiment)."""
    import numpy as np

    from openup_ompl.perception.closed_loop import ClosedLoopOptions, closed_loop
    from openup_ompl.perception.extrinsic import PerceptionOptions
    from openup_ompl.robustness import default_robustness_scene
    from openup_ompl.scene import load_scene

    problem = load_scene(default_robustness_scene())

    def judge(setup, plan, truth):  # type: ignore[no-untyped-def]
        return {"success": True, "path": np.round(plan.path, 12).tolist()}

    def run(first_seed: int, trials: int, policies: tuple[str, ...]) -> dict[tuple, list]:
        options = ClosedLoopOptions(
            policies=policies,
            noises=(1.0,),
            distances=(0.8,),
            trials=trials,
            first_seed=first_seed,
            perception=PerceptionOptions.exact(),
        )
        records = closed_loop(problem, options, judge=judge)
        return {(r["seed"], r["policy"]): r["path"] for r in records}

    through, later, alone = run(1, 2, ("0", "0.3")), run(2, 1, ("0", "0.3")), run(1, 1, ("0.3",))
    assert through[(2, "0.3")] == later[(2, "0.3")] and through[(2, "0")] == later[(2, "0")]
    assert through[(1, "0.3")] == alone[(1, "0.3")]
    assert through[(1, "0")] != through[(1, "0.3")]


@pytest.mark.parametrize(
    "name",
    [
        "closed_loop_panda",
        "closed_loop_lwa3_sdh",
        "closed_loop_physics_panda",
        "closed_loop_physics_lwa3_sdh",
    ],  # fmt: skip
)
def test_the_committed_closed_loop_tables_recompute_from_their_trials(name: str) -> None:
    """The results page's closed-loop tables are their committed trials' counts: every
    cell's successes and interval, every pair's discordant views and p."""
    import json
    from pathlib import Path

    from openup_ompl.perception.closed_loop import read_csv

    root = Path(__file__).resolve().parent.parent
    records = json.loads(
        (root / "benchmarks/results/closed_loop" / name / "closed_loop_trials.json").read_text()
    )
    table = {
        (r["policy"], r["noise"], r["distance"]): r for r in read_csv(root / f"docs/{name}.csv")
    }
    rows = summarize(records)
    assert len(rows) == len(table)
    for row in rows:
        kept = table[(str(row["policy"]), row["noise"], row["distance"])]
        assert (kept["successes"], kept["trials"]) == (row["successes"], row["trials"])
        assert kept["ci_low"] == pytest.approx(row["ci_low"], abs=1e-4)
    with (root / f"docs/{name}_pairs.csv").open(newline="") as handle:
        pairs = {(r["policy"], r["noise"], r["distance"]): r for r in csv.DictReader(handle)}
    for pair in compare_policies(records, default_reference([r["policy"] for r in records])):
        kept = pairs[(pair["policy"], str(pair["noise"]), str(pair["distance"]))]
        assert (int(kept["policy_only"]), int(kept["reference_only"])) == (
            pair["policy_only"], pair["reference_only"],
        )  # fmt: skip
        assert float(kept["p_value"]) == pytest.approx(pair["p_value"], rel=1e-3)
