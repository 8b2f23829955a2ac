"""The benchmark scripts the README quotes run to their end on tiny sizes and write what
they say they write (a script that no longer runs would otherwise go unnoticed until the
next measurement)."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import openup_ompl as oo
from openup_ompl.benchmark import default_problems_dir

ROOT = Path(__file__).resolve().parent.parent


def _run(script: str, *args: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / script), *args],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )


def test_bench_validity_runs_both_parts(tmp_path: Path) -> None:
    """Per-state table and motion table, every motion verdict agreeing between the
    all-cores and the one-thread world (the script asserts it)."""
    out = tmp_path / "validity.json"
    done = _run(
        "bench_validity.py",
        *("--states", "300", "--rounds", "1", "--motions", "12", "--motion-rounds", "1"),
        *("--json", str(out)),
    )
    assert done.returncode == 0, done.stderr[-2000:]
    result = json.loads(out.read_text())
    assert result["motions"], "no motion rows"
    for entry in result["motions"]:
        both = entry["all"]
        assert both["motions"] == entry["motions"] == 12
        # The same motions cut the same way whichever world checks them.
        assert both["batch"]["states"] == both["serial"]["states"] >= entry["motions"]


def test_bench_speed_compares_each_fixed_preshape(tmp_path: Path) -> None:
    """One seed of the Panda suite: the law's price against each ``--fixed`` preshape, every
    run solved, and the plans it re-checks pass."""
    out = tmp_path / "speed.json"
    done = _run(
        "bench_speed.py",
        *("--robots", "panda", "--planners", "ikbirrt", "--seeds", "1", "--first-seed", "2"),
        *("--cli-runs", "0", "--fixed", "w", "b", "--recheck-every", "4", "--json", str(out)),
    )
    assert done.returncode == 0, done.stderr[-2000:]
    result = json.loads(out.read_text())
    assert {p["against"] for p in result["prices"]} == {"fixed w", "fixed b"}
    assert {c["hand"] for c in result["cells"]} == {"law", "fixed w", "fixed b"}
    assert all(run["solved"] for run in result["runs"])
    assert {run["seed"] for run in result["runs"]} == {2}
    assert result["recheck"]["checked"] >= 1
    assert result["recheck"]["passed"] == result["recheck"]["checked"]
    assert re.search(r"\|\s*panda\s*\|\s*ikbirrt\s*\|\s*`b`\s*\|", done.stdout)


def _law_shape() -> object:
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        import law_shape
    finally:
        sys.path.pop(0)
    return law_shape


@pytest.mark.parametrize(("robot", "longer"), [("lwa3_sdh", True), ("panda", False)])
def test_law_shape_measures_how_far_the_fingers_reach_ahead(robot: str, longer: bool) -> None:
    """The README's mechanism for the LWA3's larger search: its law's plateau points the
    fingertips further ahead of the palm than `w` (by more than a centimetre), while the
    Panda's fingers reach as far ahead with either hand, and wider with `w`."""
    law_shape = _law_shape()
    problem = oo.load_scene(default_problems_dir(robot) / "shelf_small.toml")
    law = oo.GraspPlanningSetup(problem).law
    home = np.asarray(problem.robot.spec.home, dtype=float)
    plateau = law_shape.extents(problem.robot, home, np.asarray(law(1.0), dtype=float))
    wide = law_shape.extents(problem.robot, home, np.asarray(law.w, dtype=float))
    assert (plateau[0] - wide[0] > 0.01) is longer
    assert wide[1] > plateau[1]


def test_law_shape_follows_each_path_with_the_other_hand(tmp_path: Path) -> None:
    """One seed of the Panda suite: a path per problem and hand, counted, and the figure."""
    out = tmp_path / "shape.png"
    done = _run("law_shape.py", "--robots", "panda", "--seeds", "1", "--out", str(out))
    assert done.returncode == 0, done.stderr[-2000:]
    counts = re.search(
        r"panda: (\d+) of w's (\d+) paths .*?, (\d+) of the law's (\d+)", done.stdout
    )
    assert counts is not None, done.stdout[-2000:]
    blocked_w, paths_w, blocked_law, paths_law = map(int, counts.groups())
    assert paths_w == paths_law == 8
    assert 0 <= blocked_w <= paths_w and 0 <= blocked_law <= paths_law
    assert out.stat().st_size > 10_000


def test_perception_accuracy_prints_a_row_per_object() -> None:
    """The calibration table behind the README's perception figures: one row per object,
    its views all fitted or counted as refused."""
    done = _run("perception_accuracy.py", "--objects", "box", "can", "--noise", "1", "--views", "3")
    assert done.returncode == 0, done.stderr
    rows = [line for line in done.stdout.splitlines() if line.startswith(("| box", "| can"))]
    assert len(rows) == 2 and all("| 3 (" in row for row in rows)


@pytest.mark.slow  # plans and executes a plan of each shipped robot
def test_bench_revalidate_prints_a_row_per_robot(tmp_path: Path) -> None:
    """The re-validation cost beside the execution's: one row per shipped robot's can
    scene, every plan re-validated (its rows counted) and executed, the JSON written."""
    out = tmp_path / "revalidate.json"
    done = _run("bench_revalidate.py", "--seeds", "1", "--json", str(out))
    assert done.returncode == 0, done.stderr
    rows = [line for line in done.stdout.splitlines() if line.startswith("| ") and "_can" in line]
    assert len(rows) == len(oo.available_robots())
    scenes = json.loads(out.read_text())["scenes"]
    assert all(s["states"][0] > 1 and len(s["execute_s"]) == 1 for s in scenes.values())


def test_bench_coupling_checks_every_robot(tmp_path: Path) -> None:
    """Every robot, both state sets, every variant timed; the script fails on any verdict
    that differs from its pair-loop reference."""
    out = tmp_path / "coupling.json"
    done = _run("bench_coupling.py", "--states", "40", "--rounds", "2", "--json", str(out))
    assert done.returncode == 0, done.stderr[-2000:]
    result = json.loads(out.read_text())
    assert set(result["robots"]) == {"panda", "lwa3_sdh", "ur5_allegro"}
    for entry in result["robots"].values():
        near = entry["sets"]["near the grasp"]
        assert near["on_plateau_fraction"] == 0.0  # every state there moves the fingers
        for state_set in entry["sets"].values():
            assert state_set["states"] == 40
            assert all(t > 0 for t in state_set["median_s_per_state"].values())


def test_closed_loop_tables_joins_seed_ranges_and_refuses_a_shared_view(tmp_path: Path) -> None:
    """Two runs' trials join into one table whose counts are their sums, and a view that
    both runs hold is refused rather than counted twice."""

    def run(seeds: range, successes: dict[str, bool]) -> list[dict[str, object]]:
        return [
            {
                "noise": 1.0,
                "distance": 0.6,
                "seed": seed,
                "policy": policy,
                "success": ok,
                "u": 0.5,
                "error_mm": 2.0,
                "seen": True,
                "planned": True,
            }  # fmt: skip
            for seed in seeds
            for policy, ok in successes.items()
        ]

    a, b = tmp_path / "a.json", tmp_path / "b.json"
    a.write_text(json.dumps(run(range(1, 4), {"0": True, "covariance": True})))
    b.write_text(json.dumps(run(range(4, 6), {"0": False, "covariance": True})))
    result = _run("closed_loop_tables.py", str(a), str(b), "--out", str(tmp_path / "out"))
    assert result.returncode == 0, result.stderr
    rows = (tmp_path / "out" / "closed_loop.csv").read_text().splitlines()
    by_policy = {line.split(",")[0]: line.split(",") for line in rows[1:]}
    assert by_policy["0"][3:5] == ["5", "3"] and by_policy["covariance"][3:5] == ["5", "5"]
    assert "discordant 0 / 2" in result.stdout
    shared = _run("closed_loop_tables.py", str(a), str(a), "--out", str(tmp_path / "x"))
    assert shared.returncode != 0 and "a.json" in shared.stderr


def test_perception_every_scene_reports_each_view_and_the_check() -> None:
    """The every-scene check perceives a shipped scene with the defaults and states its
    verdict on the last line."""
    result = _run("perception_every_scene.py", "--seeds", "1", "--only", "scenes/panda_can")
    assert result.returncode == 0, result.stderr
    rows = [line for line in result.stdout.splitlines() if line.startswith("| `")]
    assert [row.split("`")[1] for row in rows] == ["scenes/panda_can.toml"]
    assert "estimated" in rows[0]
    assert result.stdout.rstrip().endswith("every scene estimated or refused in one line: True")


def test_study_trial_figure_replays_the_committed_verdicts(tmp_path: Path) -> None:
    """A committed study trial rebuilt and replayed gives the shard's verdicts (the script
    refuses otherwise), and a changed shard verdict is refused."""
    out, measured = tmp_path / "trial.png", tmp_path / "trial.json"
    args = ("--trial", "18", "--mesh-dir", str(tmp_path / "meshes"))
    result = _run("study_trial_figure.py", *args, "--out", str(out), "--json", str(measured))
    assert result.returncode == 0, result.stderr[-2000:]
    assert out.stat().st_size > 0
    rows = {row["u"]: row for row in json.loads(measured.read_text())}
    assert rows[0.3]["cause"] is None and rows[1.0]["cause"] == "fell"
    assert rows[1.0]["first_touch"]["phase"] == "reach"
    shards = tmp_path / "shards"
    shards.mkdir()
    source = ROOT / "benchmarks/results/study_lwa3_sdh_perceived/shards"
    name = next(source.glob("lwa3_sdh-thin-perceived-t10-20-*.json")).name
    data = json.loads((source / name).read_text())
    data["trials"][8]["results"]["1"]["cause"] = "no contact"
    (shards / name).write_text(json.dumps(data))
    changed = _run("study_trial_figure.py", *args, "--shards", str(shards))
    assert changed.returncode != 0 and "differs from the shard" in changed.stderr
