"""Fixed plans and offsets whose physics verdicts are recorded (``tests/data/
physics_regression.json``): the rollout's refactors and speed-ups must reproduce them.

The plans' waypoints are stored (not re-planned: a planner change does not move them) and
densified by :meth:`~openup_ompl.GraspPlanningSetup.densify`; the world is rebuilt from the
shipped scene and robot. ``python tests/physics_regression.py``
re-plans and re-records (only when a change of the verdicts is intended).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data" / "physics_regression.json"

#: (scene, planning seed, offsets [dx m, dy m, yaw rad]); the first case's first three
#: offsets are the quick tier's.
CASES: list[tuple[str, int, list[list[float]]]] = [
    ("panda_can", 1, [
        [0.0, 0.0, 0.0], [0.0, 0.01, 0.0], [0.02, 0.0, 0.0], [0.01, 0.0, 0.0],
        [0.0, -0.01, 0.0], [-0.015, 0.0, 0.0], [0.0, 0.0, 0.3], [0.15, 0.0, 0.0],
        [-0.15, 0.0, 0.0], [0.005, 0.005, 0.0], [0.015, 0.0, 0.0], [-0.02, 0.0, 0.0],
    ]),
    ("lwa3_sdh_can", 1, [
        [0.0, 0.0, 0.0], [0.0, 0.01, 0.0], [0.0, 0.03, 0.0], [-0.02, 0.0, 0.0],
        [0.02, 0.0, 0.0],
    ]),
    ("ur5_allegro_can", 1, [[0.0, 0.0, 0.0], [0.01, 0.0, 0.0], [0.0, -0.015, 0.0]]),
]  # fmt: skip

#: Numbers of a record compared (path into the record's dict).
KEYS = (
    ("steps",),
    ("touched",),
    ("lift", "object_mm"),
    ("lift", "object_peak_mm"),
    ("in_hand", "mm"),
    ("moved_before_closing", "mm"),
    ("penetration", "robot_object_mm"),
    ("penetration", "object_obstacle_mm"),
)


def plan_contents(case: dict[str, Any]) -> dict[str, Any]:
    """A plan file's contents for a stored case: its path and law on today's scene and
    robot files."""
    import openup_ompl as ou

    problem = ou.load_scene(ROOT / "scenes" / f"{case['scene']}.toml")
    robot = problem.robot
    assert problem.object is not None
    path = ou.GraspPlanningSetup(problem).densify(case["waypoints"])
    return {
        "format": "openup-plan/1",
        "planner": case["planner"],
        "seed": case["seed"],
        "robot": {
            "name": robot.spec.name,
            "urdf": str(robot.urdf),
            "package_dirs": list(robot.package_dirs),
            "palm_frame": robot.spec.palm_frame,
            "joint_names": robot.joint_names,
            "arm_joints": list(robot.spec.arm_joints),
            "hand_joints": list(robot.hand_joints),
        },
        "scene": {
            "object": problem.object.to_table(),
            "obstacles": [shape.to_table() for shape in problem.obstacles],
        },
        "start": problem.start.tolist(),
        "grasp_pose": problem.grasp_pose.tolist(),
        "hand_law": case["hand_law"],
        "path": path.tolist(),
    }


def summary(record: dict[str, Any]) -> dict[str, Any]:
    """The compared part of an execution record's contents."""
    out: dict[str, Any] = {"success": record["success"], "cause": record["cause"]}
    for key in KEYS:
        value: Any = record
        for part in key:
            value = value[part]
        out[".".join(key)] = value
    first = record["first_contact"]
    out["first_contact"] = None if first is None else [first["link"], first["phase"]]
    return out


def load() -> list[dict[str, Any]]:
    """The stored cases."""
    return json.loads(DATA.read_text())["cases"]


def record_all() -> None:
    """Plan each case and record its verdicts (rewrites the data file)."""
    import openup_ompl as ou
    from openup_ompl.physics import Rollout

    cases = []
    for scene, seed, offsets in CASES:
        problem = ou.load_scene(ROOT / "scenes" / f"{scene}.toml")
        plan = ou.GraspPlanningSetup(problem).solve(time_limit=10.0, planner="ikbirrt", seed=seed)
        data = plan.to_dict()
        case = {"scene": scene, "seed": seed, "planner": plan.planner,
                "hand_law": data["hand_law"], "waypoints": data["waypoints"]}  # fmt: skip
        contents = plan_contents(case)
        assert contents["path"] == data["path"], "densify does not give the plan's path"
        rollout = Rollout(contents)
        case["trials"] = []
        for offset in offsets:
            record = rollout.run(offset, frames=False).to_dict(frames=False)
            case["trials"].append({"offset": offset, **summary(record)})
            print(scene, offset, record["verdict"], file=sys.stderr)
        cases.append(case)
    DATA.write_text(json.dumps({"cases": cases}, indent=1) + "\n")


if __name__ == "__main__":
    record_all()
