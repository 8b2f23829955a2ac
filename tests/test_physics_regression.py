"""Physics verdicts of fixed plans and offsets stay as recorded (tests/physics_regression.py)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

pytest.importorskip("mujoco")
sys.path.insert(0, str(Path(__file__).resolve().parent))

import physics_regression as regression  # noqa: E402

from openup_ompl.physics import PhysicsOptions, Rollout  # noqa: E402


def _check(case: dict, trials: list[dict], options: PhysicsOptions | None = None) -> int:
    """Run ``trials`` of ``case`` and compare each with its recorded summary: the verdict
    always, the numbers unless the rollout ended early. Returns how many did."""
    rollout = Rollout(regression.plan_contents(case), options)
    early = 0
    for trial in trials:
        expected = {k: v for k, v in trial.items() if k != "offset"}
        record = rollout.run(trial["offset"], frames=False).to_dict(frames=False)
        got = regression.summary(record)
        where = f"{case['scene']} at {trial['offset']}"
        assert got["success"] == expected["success"], where
        assert got["cause"] == expected["cause"], where
        assert got.get("neighbours") == expected.get("neighbours"), where
        if record.get("ended_early"):
            early += 1
            continue
        for key, value in expected.items():
            if isinstance(value, float):
                assert got[key] == pytest.approx(value, rel=1e-6, abs=1e-6), (where, key)
            else:
                assert got[key] == value, (where, key)
    return early


def test_quick_verdicts_are_the_recorded_ones():
    """Three Panda trials (held, a can pushed away, a can dropped) give their recorded
    verdicts and numbers."""
    case = regression.load()[0]
    _check(case, case["trials"][:3])


@pytest.mark.slow
@pytest.mark.parametrize("index", range(3))
def test_every_recorded_verdict_is_reproduced(index):
    """Every stored plan and offset gives its recorded verdict and numbers."""
    case = regression.load()[index]
    _check(case, case["trials"])


def test_a_plan_in_memory_executes_as_its_file_contents():
    """Rollout(plan) takes the plan's problem as it is, without the file round trip, and
    gives the same record as the plan's file contents (a held and a pushed trial)."""
    import openup_ompl as ou

    problem = ou.load_scene(regression.ROOT / "scenes" / "panda_can.toml")
    plan = ou.GraspPlanningSetup(problem).solve(time_limit=5.0, planner="ikbirrt", seed=1)
    in_memory, from_file = Rollout(plan), Rollout(plan.to_dict())
    assert in_memory.source.object is problem.object
    for offset in ((0.0, 0.0, 0.0), (0.0, 0.01, 0.0)):
        a = in_memory.run(offset, frames=False).to_dict(frames=False)
        b = from_file.run(offset, frames=False).to_dict(frames=False)
        assert a == b, offset


@pytest.mark.slow
@pytest.mark.parametrize("index", range(6))
def test_the_throughput_set_keeps_its_verdicts(index):
    """The 126 trials of tests/data/physics_trials.json (six plans at the sweep's 21
    perturbations, two with a movable cup) give their recorded verdicts and numbers."""
    case = regression.load(regression.TRIALS)[index]
    _check(case, case["trials"])


@pytest.mark.slow
def test_ending_early_keeps_every_verdict_of_the_throughput_set():
    """With early_end the 126 trials keep their verdicts and neighbour flags (the
    numbers of those that ran to the end too), and some end early."""
    early = sum(
        _check(case, case["trials"], PhysicsOptions(early_end=True))
        for case in regression.load(regression.TRIALS)
    )
    assert early > 0
