"""benchmarks/bench_peers.py without the peer: our planners and the OMPL reference, one run."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType, SimpleNamespace

import numpy as np
import pytest

from openup_ompl.benchmark import default_problems_dir

SCRIPT = Path(__file__).resolve().parent.parent / "benchmarks" / "bench_peers.py"
PROBLEM = default_problems_dir("panda") / "table_pick.toml"


@pytest.fixture(scope="module")
def bench_peers() -> ModuleType:
    spec = importlib.util.spec_from_file_location("bench_peers", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up while it loads
    spec.loader.exec_module(module)
    return module


def test_peers_share_start_goal_and_a_pinned_hand(bench_peers: ModuleType) -> None:
    """The peers' problem: the start, one IK goal, the hand pinned at w in the limits."""
    peers = bench_peers.prepare(PROBLEM, 0.006, 0.4)
    fixed = peers.fixed
    robot = fixed.problem.robot
    hand = fixed.law.fixed_clipped
    assert np.allclose(peers.q_start[robot.arm_idx], fixed.problem.start)
    assert np.allclose(peers.q_goal[robot.arm_idx], peers.goal)
    assert fixed.goal.task_error(peers.goal) <= 1e-3
    lower, upper = peers.pinned_model.lowerPositionLimit, peers.pinned_model.upperPositionLimit
    assert np.array_equal(lower[robot.hand_idx], hand)
    assert np.array_equal(upper[robot.hand_idx], hand)
    assert np.array_equal(lower[robot.arm_idx], robot.arm_lower)
    # No robot point moves more than the 6 mm resolution in one joint-space step.
    assert peers.step * np.linalg.norm(fixed.checker.plateau_weights) <= 0.006 + 1e-12


def test_run_without_peer_solves_and_rechecks(bench_peers: ModuleType) -> None:
    """One seed of ikbirrt, rrtconnect and the OMPL reference: solved, counted, rechecked."""
    variants = ("ikbirrt", "rrtconnect", "ompl-reference")
    result = bench_peers.run_peers([PROBLEM], [1], 5.0, variants)
    assert [r["variant"] for r in result["runs"]] == list(variants)
    assert all(r["solved"] for r in result["runs"])
    cells = result["summary"]["per_problem"]["panda.table_pick"]
    # The reference's path is re-checked by our exact check; whether it passes depends on
    # OMPL's process-wide generator (it may graze an obstacle closer than our margin).
    assert cells["ompl-reference"]["checked"] == 1
    assert cells["ompl-reference"]["valid"] in (0, 1)
    assert result["summary"]["all_ours_solved"]
    assert len(result["plans"]) == 2
    assert bench_peers._common.recheck_plans(result["plans"]) == (2, 2)


def test_main_skips_an_absent_peer_in_one_line(
    bench_peers: ModuleType, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    """Without pyroboplan the script says so on stderr, runs the rest and exits 0."""
    monkeypatch.setattr(bench_peers, "pyroboplan_version", lambda: None)
    code = bench_peers.main(["--problems", str(PROBLEM), "--seeds", "1", "--time", "5"])
    out, err = capsys.readouterr()
    assert code == 0
    assert "pyroboplan is not installed" in err
    assert "pyroboplan did not run" in out
    assert "recheck: 2/2 plans pass" in out


def test_summary_names_every_problem_under_the_per_problem_target(
    bench_peers: ModuleType,
) -> None:
    """A geometric mean over 50x does not hide a problem under 10x: it is named, the
    least ratio reported, and the target not met."""
    problems = [SimpleNamespace(name=name) for name in ("a", "b", "c")]
    peer = {"a": 8.0, "b": 0.6, "c": 9.0}  # pyroboplan's seconds; ours take 0.01 s
    runs = [
        {"problem": name, "variant": variant, "solved": True, "time_s": t, "wall_s": t}
        for name in peer
        for variant, t in (("ikbirrt", 0.01), ("pyroboplan", peer[name]))
    ]
    summary = bench_peers.summarize(problems, runs, ("ikbirrt", "pyroboplan"))
    assert summary["geomean"]["pyroboplan/ikbirrt"] >= bench_peers.TARGET
    assert summary["below_scene_target"] == []
    assert summary["target_met"]
    peer["b"] = 0.05  # 5x
    runs = [
        r if r["variant"] != "pyroboplan" else {**r, "time_s": peer[r["problem"]]} for r in runs
    ]
    summary = bench_peers.summarize(problems, runs, ("ikbirrt", "pyroboplan"))
    assert summary["below_scene_target"] == ["b"]
    assert summary["least_ratio"] == {"problem": "b", "pyroboplan/ikbirrt": pytest.approx(5.0)}
    assert not summary["target_met"]
    report = bench_peers.report(
        {"summary": summary, "steps_rad": {"b": 0.01}, "recheck": (3, 3)},
        bench_peers._common.machine_info(),
        {
            "variants": ["ikbirrt", "pyroboplan"],
            "seeds": [1],
            "time": 1.0,
            "range": 0.4,
            "peer_range": 2.0,
            "ompl_seed": 1,
        },
    )
    assert "under 10×: b" in report and "5.0× on b" in report
