"""The study: paired trials, resumable shards, its CSVs and its command."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from openup_ompl.__main__ import main
from openup_ompl._resources import data_dir
from openup_ompl.exceptions import ConfigError
from openup_ompl.perception.uncertainty import arrival_fraction
from openup_ompl.study import StudyOptions, run_study
from openup_ompl.study.errors import believe, parse_error
from openup_ompl.study.families import instance_problem, parse_families, template_scene
from openup_ompl.study.report import MAP_COLUMNS, PAIR_COLUMNS, map_rows, pair_rows
from openup_ompl.study.run import run_trial, trial_seeds
from openup_ompl.study.stats import mcnemar_exact, wilson_interval


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as handle:
        return list(csv.DictReader(handle))


def test_trial_seeds_are_deterministic_and_distinct() -> None:
    """The same (seed, family, error, trial) gives the same streams; another trial others."""
    a = trial_seeds(1, "panda-can", "pose-1cm", 0)
    b = trial_seeds(1, "panda-can", "pose-1cm", 0)
    c = trial_seeds(1, "panda-can", "pose-1cm", 1)
    assert a[2] == b[2] != c[2]
    assert a[0].random() == b[0].random() != c[0].random()
    assert a[1].random() == b[1].random()


def test_policies_of_a_trial_share_instance_error_and_plan_seed(tmp_path: Path) -> None:
    """Run with different policy lists, a trial draws the same instance, belief and plan
    seed, and a policy common to both gets the same verdict (pairing)."""
    family = parse_families(["panda-clutter"])[0]
    template = template_scene(family)
    source = parse_error("pose-2cm")
    first = run_trial(family, template, source, ["0", "1"], 3, seed=5, mesh_dir=tmp_path)
    second = run_trial(family, template, source, ["1", "covariance"], 3, seed=5, mesh_dir=tmp_path)
    for key in ("object", "obstacles", "offset", "plan_seed"):
        assert first[key] == second[key]
    assert first["results"]["1"] == second["results"]["1"]
    assert set(first["results"]) == {"0", "1"}
    # The belief really is off the truth by the drawn error.
    assert np.hypot(*first["offset"][:2]) > 0


def test_direct_error_moves_the_belief_not_the_truth() -> None:
    """A pose error moves the believed object and its grasp together; the truth stays."""
    family = parse_families(["panda-can"])[0]
    truth = instance_problem(family, np.random.default_rng(0), template_scene(family))
    belief = believe(truth, parse_error("pose-1cm"), np.random.default_rng(1))
    assert belief.believed is not None and belief.believed.object is not None
    assert truth.object is not None
    moved = belief.believed.object.pose[:2] - truth.object.pose[:2]
    grasp_moved = belief.believed.grasp_pose[:2] - truth.grasp_pose[:2]
    assert np.linalg.norm(moved) > 0
    assert np.allclose(moved, grasp_moved, atol=2e-3)  # turned by the yaw about the object


def test_study_resumes_from_its_shards(tmp_path: Path) -> None:
    """A rerun reuses every finished chunk; a lost shard alone is run again."""
    options = StudyOptions(
        tuple(parse_families(["panda-can"])),
        errors=("pose-0.5cm",),
        policies=("0", "1"),
        trials=2,
        chunk=1,
    )
    first = run_study(options, tmp_path, workers=1, quiet=True)
    shards = sorted((tmp_path / "shards").glob("*.json"))
    assert len(shards) == 2
    stamps = [s.stat().st_mtime_ns for s in shards]
    shards[0].unlink()
    second = run_study(options, tmp_path, workers=1, quiet=True)
    assert shards[0].exists() and shards[1].stat().st_mtime_ns == stamps[1]
    assert first.rows == second.rows


def test_study_csv_columns(tmp_path: Path) -> None:
    """Both CSVs have their columns; intervals and p-values recompute from their counts."""
    options = StudyOptions(
        tuple(parse_families(["panda-can"])), errors=("pose-1cm",), policies=("0", "adaptive"),
        trials=2,
    )  # fmt: skip
    result = run_study(options, tmp_path, workers=1, quiet=True)
    rows = _rows(result.map_csv)
    assert tuple(rows[0]) == MAP_COLUMNS
    assert [r["policy"] for r in rows] == ["0", "adaptive"]
    for row in rows:
        assert int(row["trials"]) == 2
        low, high = wilson_interval(int(row["successes"]), int(row["trials"]))
        assert float(row["ci_low"]) == pytest.approx(low, rel=1e-5)
        assert float(row["ci_high"]) == pytest.approx(high, rel=1e-5)
        assert float(row["ci_low"]) <= float(row["rate"]) <= float(row["ci_high"])
    pairs = _rows(result.pairs_csv)
    assert tuple(pairs[0]) == PAIR_COLUMNS
    assert [(p["policy_a"], p["policy_b"]) for p in pairs] == [("0", "adaptive")]
    p = pairs[0]
    expected = mcnemar_exact(int(p["a_only"]), int(p["b_only"]))
    assert float(p["p_value"]) == pytest.approx(expected, rel=1e-5)


def test_study_options_refuse_bad_values() -> None:
    """Unknown errors and policies, duplicate policies and zero trials are ConfigErrors."""
    families = tuple(parse_families(["panda-can"]))
    for bad in (
        {"errors": ("pose-xcm",)},
        {"policies": ("0", "0.0")},
        {"policies": ("2",)},
        {"trials": 0},
    ):
        with pytest.raises(ConfigError):
            StudyOptions(families, **bad)  # type: ignore[arg-type]


@pytest.mark.parametrize("scene", ["panda_can.toml", "lwa3_sdh_can.toml", "ur5_allegro_can.toml"])
def test_study_command_on_a_scene(
    tmp_path: Path, scene: str, capsys: pytest.CaptureFixture
) -> None:
    """``study --scene`` on each robot's shipped scene writes both CSVs (2 trials)."""
    out = tmp_path / "out"
    status = main(
        ["study", "--scene", str(data_dir("scenes") / scene), "--error", "pose-1cm",
         "--policies", "0", "covariance", "--trials", "2", "--workers", "1", "--quiet",
         "--out", str(out)]
    )  # fmt: skip
    assert status == 0
    rows = _rows(out / "uncertainty_map.csv")
    assert {r["policy"] for r in rows} == {"0", "covariance"}
    assert all(int(r["trials"]) == 2 for r in rows)
    assert _rows(out / "uncertainty_pairs.csv")
    assert "uncertainty_map.csv" in capsys.readouterr().out


def test_study_command_bad_input_exits_2(capsys: pytest.CaptureFixture, tmp_path: Path) -> None:
    """A bad family is one line on stderr and exit status 2."""
    status = main(["study", "--family", "panda-foo", "--out", str(tmp_path / "x")])
    assert status == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "panda-foo" in err[0]


def _synthetic(family: str, error: str, held: list[tuple[bool, bool]]) -> dict:
    trials = [
        {"trial": i, "results": {
            "0": {"u": 0.0, "planned": True, "held": a, "cause": None},
            "1": {"u": 1.0, "planned": True, "held": b, "cause": None},
        }}
        for i, (a, b) in enumerate(held)
    ]  # fmt: skip
    return {"family": family, "error": error, "trials": trials}


def test_pooled_rows_sum_the_cells_and_stay_paired() -> None:
    """With two families, 'all' rows add their counts and pair trial by trial."""
    records = [
        _synthetic("a", "pose-1cm", [(True, True), (False, True), (False, True)]),
        _synthetic("b", "pose-1cm", [(True, False), (False, True)]),
    ]
    rows = {(r["family"], r["policy"]): r for r in map_rows(records, ["0", "1"])}
    assert rows[("all", "0")]["successes"] == 2 and rows[("all", "0")]["trials"] == 5
    assert rows[("all", "1")]["successes"] == 4
    pairs = {p["family"]: p for p in pair_rows(records, ["0", "1"])}
    assert (pairs["all"]["a_only"], pairs["all"]["b_only"], pairs["all"]["n"]) == (1, 3, 5)
    assert pairs["all"]["p_value"] == pytest.approx(mcnemar_exact(1, 3))


def test_adaptive_plans_at_the_need_and_falls_back_when_the_scene_forbids_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``adaptive`` plans at the covariance rule's need taken where the fingertips reach
    the object (at least the rule's ``u``); when that plan fails it plans again at the
    narrowest hand, reusing a plan the trial already made at that ``u``."""
    import openup_ompl.study.run as run

    family = parse_families(["panda-clutter"])[0]
    template = template_scene(family)
    source = parse_error("pose-2cm")
    calls: list[float] = []

    def planned_only_closed(believed, truth, u, plan_seed, planner, time_limit):  # type: ignore[no-untyped-def]
        calls.append(u)
        return {"planned": u == 0.0, "held": u == 0.0, "cause": None if u == 0.0 else "plan failed"}

    monkeypatch.setattr(run, "_execute", planned_only_closed)
    record = run_trial(
        family, template, source, ["0", "covariance", "adaptive"], 1, seed=3, mesh_dir=tmp_path
    )
    rule = record["results"]["covariance"]["u"]
    adaptive = record["results"]["adaptive"]
    need = adaptive["fallback_from"]
    assert 0 < rule <= need
    assert adaptive["u"] == 0.0 and adaptive["held"]
    assert sorted(calls) == sorted({0.0, rule, need})  # each u planned once in the trial

    calls.clear()
    monkeypatch.setattr(run, "_execute", lambda *a: {"planned": True, "held": True, "cause": None})
    record = run_trial(family, template, source, ["covariance", "adaptive"], 1, seed=3,
                       mesh_dir=tmp_path)  # fmt: skip
    assert record["results"]["adaptive"]["u"] == need
    assert "fallback_from" not in record["results"]["adaptive"]


def test_capped_never_opens_wider_than_the_need() -> None:
    """``capped`` is the covariance rule's ``u`` cut by the swept clearance, never above it."""
    from openup_ompl.study.geometry import HandSweep
    from openup_ompl.study.policies import policy_u

    family = parse_families(["panda-clutter"])[0]
    template = template_scene(family)
    for trial in range(3):
        instance_rng, error_rng, _ = trial_seeds(2, family.name, "pose-2cm", trial)
        truth = instance_problem(family, instance_rng, template)
        belief = believe(truth, parse_error("pose-2cm"), error_rng)
        assert belief.believed is not None and belief.evidence is not None
        safe = HandSweep(belief.believed).largest_safe_u()
        need = policy_u("covariance", belief.evidence, belief.believed, None)
        capped = policy_u("capped", belief.evidence, belief.believed, safe)
        assert capped == pytest.approx(min(need, safe))
        adaptive = policy_u("adaptive", belief.evidence, belief.believed, safe)
        share = arrival_fraction(belief.believed, belief.evidence.sizes)
        assert adaptive == pytest.approx(min(need / share, 1.0)) and adaptive >= need
