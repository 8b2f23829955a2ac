"""Plans of a fixed set of problems, hands and seeds are the ones recorded before the
planning modules were restructured: a refactor changes no plan.

Run this file as a script to record the reference again (only after a change that is
meant to change plans)::

    python tests/test_plan_regression.py
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from ompl import util as ompl_util

import openup_ompl as oo
from openup_ompl.benchmark import default_problems_dir

REFERENCE = Path(__file__).resolve().parent / "data" / "plan_reference.json"
SCENES = Path(__file__).resolve().parent / "scenes"
#: (scene, fixed hand or None for the law, seed), all planned with IKBiRRT (seeded whole).
CASES: tuple[tuple[str, str | None, int], ...] = tuple(
    (f"{robot}/{name}", hand, seed)
    for robot in ("panda", "lwa3_sdh", "ur5_allegro")
    for name in ("table_pick", "shelf_small")
    for hand in (None, "w")
    for seed in (1, 2)
) + (("tests/panda_drawer", None, 3), ("tests/panda_slot", None, 3))

ompl_util.setLogLevel(ompl_util.LOG_ERROR)


def _scene_path(scene: str) -> Path:
    kind, name = scene.split("/")
    folder = SCENES if kind == "tests" else default_problems_dir(kind)
    return folder / f"{name}.toml"


def _plan_summary(scene: str, hand: str | None, seed: int) -> dict[str, Any]:
    """What is compared of one plan: its waypoints whole, its path's shape and sums."""
    problem = oo.load_scene(_scene_path(scene))
    plan = oo.GraspPlanningSetup(problem, fixed_hand=hand).solve(5.0, "ikbirrt", seed)
    return {
        "waypoints": plan.waypoints.tolist(),
        "path_shape": list(plan.path.shape),
        "path_column_sums": plan.path.sum(axis=0).tolist(),
        "path_last_row": plan.path[-1].tolist(),
    }


def _key(scene: str, hand: str | None, seed: int) -> str:
    return f"{scene} hand={hand or 'law'} seed={seed}"


@pytest.fixture(scope="module")
def reference() -> dict[str, Any]:
    return json.loads(REFERENCE.read_text())  # type: ignore[no-any-return]


@pytest.mark.parametrize(("scene", "hand", "seed"), CASES)
def test_plan_is_the_recorded_one(
    reference: dict[str, Any], scene: str, hand: str | None, seed: int
) -> None:
    """IKBiRRT's plan of a fixed problem, hand and seed has the recorded waypoints, the
    recorded number of path rows, and the same path (its column sums and last row)."""
    expected = reference[_key(scene, hand, seed)]
    got = _plan_summary(scene, hand, seed)
    assert got["path_shape"] == expected["path_shape"]
    np.testing.assert_allclose(got["waypoints"], expected["waypoints"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(
        got["path_column_sums"], expected["path_column_sums"], rtol=1e-12, atol=1e-9
    )
    np.testing.assert_allclose(got["path_last_row"], expected["path_last_row"], atol=1e-12)


if __name__ == "__main__":
    data = {_key(*case): _plan_summary(*case) for case in CASES}
    REFERENCE.write_text(json.dumps(data, indent=0) + "\n")
    sys.stdout.write(f"recorded {len(data)} plans in {REFERENCE}\n")
