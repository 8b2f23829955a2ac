"""The soak script (``benchmarks/soak.py``) on a tiny size: its plans re-check valid, its
shards resume, and its re-check refuses a tampered plan and finds every colliding state."""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import openup_ompl as oo

ROOT = Path(__file__).resolve().parent.parent


def _soak(*args: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "soak.py"), "--quiet", *args],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=900,
    )


@pytest.mark.slow
def test_soak_plans_recheck_and_resume(tmp_path: Path) -> None:
    """Two instances (a hand-written Panda scene's and a generated LWA3-SDH family's) plan
    and re-check valid, and the results section names the command and no invalid plan; a
    larger rerun adds the third instance's shard and keeps the two made before."""
    base = ("--planners", "ikbirrt", "--us", "0.3", "--robots", "panda", "lwa3_sdh")
    done = _soak("--plans", "2", *base, "--out", str(tmp_path))
    assert done.returncode == 0, done.stderr[-2000:]
    summary = json.loads((tmp_path / "soak.json").read_text())
    assert summary["plans"] == 2 and summary["counts"].get("invalid", 0) == 0
    assert summary["counts"].get("valid", 0) >= 1
    assert set(summary["groups"]) >= {"robot panda", "robot lwa3_sdh", "planner ikbirrt"}
    page = (tmp_path / "soak.md").read_text()
    assert page.startswith("`python benchmarks/soak.py --quiet --plans 2 ")
    assert "| robot lwa3_sdh |" in page and "Invalid plans: none." in page
    shards = {p: p.stat().st_mtime_ns for p in (tmp_path / "shards").glob("*.json")}
    assert len(shards) == 2
    again = _soak("--plans", "3", *base, "--out", str(tmp_path))
    assert again.returncode == 0, again.stderr[-2000:]
    after = {p: p.stat().st_mtime_ns for p in (tmp_path / "shards").glob("*.json")}
    assert len(after) == 3 and all(after[p] == t for p, t in shards.items())
    assert json.loads((tmp_path / "soak.json").read_text())["plans"] == 3


def test_soak_recheck_refuses_a_tampered_plan() -> None:
    """The soak's re-check passes a plan as made and refuses it once a hand column is
    moved off the law or a row is moved through the table."""
    soak = pytest.importorskip("benchmarks.soak")
    recheck = soak._recheck_module()
    problem = oo.load_scene(ROOT / "scenes" / "panda_can.toml")
    plan = oo.GraspPlanningSetup(problem, u=0.3).solve(5.0, "ikbirrt", 1)
    assert soak._recheck(plan, recheck, soak.RECHECK_STEP)["valid"]
    hand = plan.path.copy()
    hand[len(hand) // 2, problem.robot.hand_idx[0]] += 0.005
    off_law = soak._recheck(oo.Plan(**{**vars(plan), "path": hand}), recheck, 0.01)
    assert not off_law["valid"] and off_law["hand_error"] > 1e-3
    sunk = plan.path.copy()
    sunk[-2, problem.robot.arm_idx[3]] -= 0.5  # the elbow folded: the hand in the table
    through = soak._recheck(oo.Plan(**{**vars(plan), "path": sunk}), recheck, 0.01)
    assert not through["valid"] and through["colliding"]


@pytest.mark.parametrize("scene", ["panda_bottle", "lwa3_sdh_can", "ur5_allegro_can"])
def test_recheck_broad_phase_flags_the_states_every_pair_flags(scene: str) -> None:
    """The re-check's batched broad-phase check flags exactly the states that Pinocchio's
    every-pair loop flags, on states near a plan and across the joint limits."""
    soak = pytest.importorskip("benchmarks.soak")
    recheck = soak._recheck_module()
    plan = oo.GraspPlanningSetup(oo.load_scene(ROOT / "scenes" / f"{scene}.toml")).solve(
        5.0, "ikbirrt", 1
    )
    model, geometry = recheck.plan_geometry(json.loads(json.dumps(plan.to_dict())))
    rng = np.random.default_rng(0)
    lower = np.maximum(model.lowerPositionLimit, -np.pi)
    upper = np.minimum(model.upperPositionLimit, np.pi)
    near = plan.path[rng.integers(len(plan.path), size=150)]
    near = near + rng.normal(0.0, 0.3, near.shape)
    states = np.clip(np.vstack([near, rng.uniform(lower, upper, (150, model.nq))]), lower, upper)
    data, geometry_data = model.createData(), geometry.createData()
    every_pair = [
        pin.computeCollisions(model, data, geometry, geometry_data, q, True) for q in states
    ]
    flagged = recheck.colliding_states(model, geometry, states)
    assert 0 < sum(every_pair) < len(states)
    assert flagged.tolist() == every_pair


def test_soak_blocks_cover_every_instance_once_and_keep_their_keys(tmp_path: Path) -> None:
    """The tasks' blocks hold every instance of the round-robin once (whole blocks but
    each source's last), and a larger ``--plans`` keeps every whole block's key."""
    soak = pytest.importorskip("benchmarks.soak")
    options = soak.SoakOptions(plans=300, planners=("ikbirrt",), us=(0.3,), block=4)
    tasks = soak.make_tasks(options, tmp_path)
    sources = soak.generators(options.robots)
    instances = [
        (task.kwargs["source"]["name"], task.kwargs["first"] + k)
        for task in tasks
        for k in range(task.kwargs["count"])
    ]
    expected = [(sources[k % len(sources)]["name"], k // len(sources)) for k in range(300)]
    assert sorted(instances) == sorted(expected)
    assert all(1 <= task.kwargs["count"] <= 4 for task in tasks)
    whole = {task.key for task in tasks if task.kwargs["count"] == 4}
    more = soak.make_tasks(dataclasses.replace(options, plans=600), tmp_path)
    assert whole and whole <= {task.key for task in more}
