"""Fixed plans and offsets whose physics verdicts are recorded (``tests/data/
physics_regression.json``): the rollout's refactors and speed-ups must reproduce them.

The plans' waypoints are stored (not re-planned: a planner change does not move them) and
densified by :meth:`~openup_ompl.GraspPlanningSetup.densify`; the world is rebuilt from the
shipped scene and robot. ``python tests/physics_regression.py``
re-plans and re-records (only when a change of the verdicts is intended); ``--trials``
does so for the throughput set.
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

#: The sweep's 21 perturbations: the nominal pose, then +-x and +-y at five distances [m].
SWEEP = [[0.0, 0.0, 0.0]] + [
    [sx * d, sy * d, 0.0]
    for d in (0.005, 0.01, 0.015, 0.02, 0.03)
    for sx, sy in ((1, 0), (-1, 0), (0, 1), (0, -1))
]
#: The throughput set (``tests/data/physics_trials.json``, 126 trials): six plans at the
#: sweep's perturbations; the bottle scene has a movable cup beside the bottle.
TRIAL_CASES: list[tuple[str, int, list[list[float]]]] = [
    ("panda_can", 2, SWEEP),
    ("panda_can", 3, SWEEP),
    ("lwa3_sdh_can", 2, SWEEP),
    ("ur5_allegro_can", 2, SWEEP),
    ("panda_bottle", 1, SWEEP),
    ("panda_bottle", 2, SWEEP),
]
TRIALS = ROOT / "tests" / "data" / "physics_trials.json"

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
    if record.get("neighbours"):
        out["neighbours"] = [[n["name"], n["moved"], n["tipped"]] for n in record["neighbours"]]
    return out


def load(path: Path = DATA) -> list[dict[str, Any]]:
    """The stored cases (of the regression file, or of ``path``)."""
    return json.loads(path.read_text())["cases"]


def record_all(specs: list[tuple[str, int, list[list[float]]]] = CASES, path: Path = DATA) -> None:
    """Plan each case and record its verdicts (rewrites the data file)."""
    import openup_ompl as ou
    from openup_ompl.physics import Rollout

    cases = []
    for scene, seed, offsets in specs:
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
    path.write_text(json.dumps({"cases": cases}, indent=1) + "\n")


def replay(seed: int, cases: dict[str, list[int]]) -> dict[str, Any]:
    """An executor task (``physics_regression:replay``): each of the throughput set's
    ``cases`` (its index, as a string: JSON keys) run at its trials (indices into its
    offsets) with the sweep's settings (``PhysicsOptions(early_end=True)``), the object's
    jitter seeded by ``seed``.

    Returns:
        ``{"records"}``: each trial's execution record without frames, in order.
    """
    from openup_ompl.physics import PhysicsOptions, Rollout

    stored = load(TRIALS)
    records = []
    for index, trials in cases.items():
        case = stored[int(index)]
        rollout = Rollout(plan_contents(case), PhysicsOptions(early_end=True))
        for i in trials:
            record = rollout.run(case["trials"][i]["offset"], seed=seed, frames=False)
            records.append(record.to_dict(frames=False))
    return {"records": records}


if __name__ == "__main__":
    if sys.argv[1:] == ["--trials"]:
        record_all(TRIAL_CASES, TRIALS)
    else:
        record_all()
