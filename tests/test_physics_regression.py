"""Physics verdicts of fixed plans and offsets stay as recorded (tests/physics_regression.py)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

pytest.importorskip("mujoco")
sys.path.insert(0, str(Path(__file__).resolve().parent))

import physics_regression as regression  # noqa: E402

from openup_ompl.physics import Rollout  # noqa: E402


def _check(case: dict, trials: list[dict]) -> None:
    """Run ``trials`` of ``case`` and compare each with its recorded summary."""
    rollout = Rollout(regression.plan_contents(case))
    for trial in trials:
        expected = {k: v for k, v in trial.items() if k != "offset"}
        record = rollout.run(trial["offset"], frames=False).to_dict(frames=False)
        got = regression.summary(record)
        where = f"{case['scene']} at {trial['offset']}"
        assert got["success"] == expected["success"], where
        assert got["cause"] == expected["cause"], where
        for key, value in expected.items():
            if isinstance(value, float):
                assert got[key] == pytest.approx(value, rel=1e-6, abs=1e-6), (where, key)
            else:
                assert got[key] == value, (where, key)


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
