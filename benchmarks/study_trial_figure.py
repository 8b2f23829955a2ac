"""One study trial rebuilt, replayed in physics with its frames, and drawn policy by policy.

The trial is rebuilt as :func:`openup_ompl.study.run.run_trial` builds it (the same seeds,
instance, belief and plan seed; each plan at the belief with the study's planner settings,
OMPL reseeded before it), and each policy's plan is executed against the truth as the
study's judge executes it (:func:`~openup_ompl.physics.sweep.physics_judge`: the true
object in the world, ``PhysicsOptions(early_end=True)``), here keeping the frames. The
rebuilt verdicts must equal the committed shard's, or the script stops. The judge ends a
rollout early (``early_end``: at an obstacle's first touch, or in the hold once the object
rests out of the hand), and its frames stop there; ``--full`` runs to the end instead
(then the cause, not the verdict's numbers, must match the shard's).

The figure has one row per policy: the hand where the palm is as near the grasp (``d``)
as at the earliest first touch during a reach, at the end of the reach, closed, and at
the top of the lift (one view; the believed stick's axis dashed). Printed per policy:
the first touch (link, ``d``), the aperture (thumb tip to the middle of the finger tips)
and the palm's offset from the grasp there, the height on the stick it touched, the
fingers' closest pass by the believed and the true stick before it, the stick's motion
and tilt after the reach, the squeeze and the lift, the believed and true positions.

Run (the study's seed-2 LWA3-SDH perceived set; seconds per trial)::

    python benchmarks/study_trial_figure.py --trial 18 --out docs/results/study_lwa3_stick.png
    python benchmarks/study_trial_figure.py --trial 100 110 111 --json stick.json
"""

from __future__ import annotations

import argparse
import dataclasses
import glob
import json
import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from openup_ompl.exceptions import InvalidProblem, PlanningFailed
from openup_ompl.physics.options import PhysicsOptions
from openup_ompl.physics.record import ExecutionRecord
from openup_ompl.physics.sweep import physics_trial
from openup_ompl.scene import Problem, Shape
from openup_ompl.study.errors import Belief, believe, parse_error
from openup_ompl.study.families import instance_problem, parse_families, template_scene
from openup_ompl.study.policies import FALLBACK_U, policy_u
from openup_ompl.study.run import plan_at_belief, trial_seeds

ROOT = Path(__file__).resolve().parent.parent
SHARDS = ROOT / "benchmarks" / "results" / "study_lwa3_sdh_perceived" / "shards"
#: Tip frames of the LWA3-SDH: the aperture is the thumb tip's distance to the fingers'.
FINGER_TIPS = ("sdh_finger1_tip", "sdh_finger2_tip")
THUMB_TIP = "sdh_thumb_tip"


@dataclass
class Replay:
    """One policy of one trial, replayed.

    Attributes:
        policy, u: The policy's name and its ``u``.
        record: The rollout's execution record (with frames).
        shard: The committed shard's result of this policy.
        believed, truth: The believed object (the plan's) and the true one (the world's).
        grasp: The planned grasp's position [m] (at the belief).
    """

    policy: str
    u: float
    record: ExecutionRecord
    shard: dict[str, Any]
    believed: Shape
    truth: Shape
    grasp: np.ndarray


def shard_trial(shards: Path, family: str, error: str, trial: int) -> dict[str, Any]:
    """The committed record of trial ``trial`` of ``(family, error)`` in ``shards``."""
    for name in sorted(glob.glob(str(shards / f"{family}-{error}-t*.json"))):
        data = json.loads(Path(name).read_text())
        for record in data["trials"]:
            if record["trial"] == trial:
                return dict(record)
    sys.exit(f"no trial {trial} of {family} / {error} in {shards}")


def rebuild(
    family_name: str, error: str, trial: int, seed: int, mesh_dir: Path
) -> tuple[Problem, Belief, int]:
    """The trial's truth, belief and plan seed, as :func:`run_trial` draws them."""
    (family,) = parse_families([family_name])
    source = parse_error(error)
    instance_rng, error_rng, plan_seed = trial_seeds(seed, family.name, source.name, trial)
    truth = instance_problem(family, instance_rng, template_scene(family), mesh_dir)
    return truth, believe(truth, source, error_rng), plan_seed


def replay(
    truth: Problem,
    belief: Belief,
    plan_seed: int,
    u: float,
    args: argparse.Namespace,
) -> ExecutionRecord | None:
    """Plan at the belief as the study does (:func:`plan_at_belief`), then run the judge's rollout
    (:func:`~openup_ompl.physics.sweep.physics_judge`) with its frames kept; ``None`` if
    the plan failed."""
    from openup_ompl.physics.rollout import Rollout

    assert belief.believed is not None and truth.object is not None
    try:
        _, plan = plan_at_belief(belief.believed, u, plan_seed, args.planner, args.time)
    except (PlanningFailed, InvalidProblem):
        return None
    true = Shape.from_table(truth.object.to_table(), "truth object", is_object=True)
    physics = PhysicsOptions(early_end=not args.full)
    return Rollout(plan, physics, scene_object=true).run((0.0, 0.0, 0.0), frames=True)


def _tilt(pose: np.ndarray) -> float:
    """The turn [deg] of an ``[x, y, z, qx, qy, qz, qw]`` pose's z axis from the vertical."""
    z = pin.Quaternion(pose[6], pose[3], pose[4], pose[5]).toRotationMatrix()[:, 2]
    return math.degrees(math.acos(min(1.0, max(-1.0, float(z[2])))))


def _last(phases: list[str], names: tuple[str, ...]) -> int | None:
    indices = [i for i, p in enumerate(phases) if p in names]
    return indices[-1] if indices else None


def _full(model: pin.Model, names: list[str], q: Any) -> np.ndarray:
    """Pinocchio's configuration of a frame's joint values ``q`` (joints ``names``)."""
    full = pin.neutral(model)
    full[[model.joints[model.getJointId(n)].idx_q for n in names]] = q
    return full


def hand_at(truth: Problem, names: list[str], q: list[float], grasp: np.ndarray) -> Any:
    """At frame ``q``: the thumb tip's distance [m] to the middle of the two finger tips,
    and the palm's position [m] from the grasp's (world axes)."""
    model = truth.robot.model
    data = model.createData()
    pin.framesForwardKinematics(model, data, _full(model, names, q))
    palm = np.asarray(data.oMf[truth.robot.palm_frame_id].translation) - grasp

    def tip(frame: str) -> np.ndarray:
        return np.asarray(data.oMf[model.getFrameId(frame)].translation)

    fingers = (tip(FINGER_TIPS[0]) + tip(FINGER_TIPS[1])) / 2
    return float(np.linalg.norm(tip(THUMB_TIP) - fingers)), palm


def touch_height(truth: Problem, names: list[str], q: list[float], pose: np.ndarray,
                 link: str) -> tuple[float, float]:  # fmt: skip
    """Where ``link`` (its collision geometry) is nearest the stick at frame ``q``: the
    height [m] of that point above the stick's lower end along its axis, and the gap [m]."""
    import coal

    robot = truth.robot
    model, geometry = robot.model, robot.collision_model
    data = model.createData()
    placements = geometry.createData()
    pin.forwardKinematics(model, data, _full(model, names, q))
    pin.updateGeometryPlacements(model, data, geometry, placements)
    assert truth.object is not None
    stick = dataclasses.replace(truth.object, pose=np.asarray(pose))
    where = stick.placement
    best = (math.inf, math.nan)
    for i, g in enumerate(geometry.geometryObjects):
        if model.frames[g.parentFrame].name != link:
            continue
        placed_at = placements.oMg[i]
        result = coal.DistanceResult()
        link_at = coal.Transform3s(placed_at.rotation, placed_at.translation)
        stick_at = coal.Transform3s(where.rotation, where.translation)
        request = coal.DistanceRequest()
        gap = coal.distance(g.geometry, link_at, stick.geometry(), stick_at, request, result)
        if gap < best[0]:
            local = where.actInv(np.asarray(result.getNearestPoint2()))
            best = (float(gap), float(local[2]) + (stick.length or 0.0) / 2)
    return best[1], best[0]


def clearances(truth: Problem, names: list[str], rows: np.ndarray,
               sticks: list[Shape]) -> np.ndarray:  # fmt: skip
    """Per frame (``rows``: its joint values) and per stick, the smallest distance [m] of a
    hand geometry (a link a hand joint moves) to that stick; shape ``(frames, sticks)``."""
    import coal

    from openup_ompl._model import moved_by

    robot = truth.robot
    model, geometry = robot.model, robot.collision_model
    data, placements = model.createData(), geometry.createData()
    hand = [i for i, m in enumerate(moved_by(model, geometry, robot.hand_joints)) if m]
    targets = [(s.geometry(), coal.Transform3s(s.placement.rotation, s.placement.translation))
               for s in sticks]  # fmt: skip
    out = np.full((len(rows), len(sticks)), np.inf)
    for k, row in enumerate(rows):
        pin.forwardKinematics(model, data, _full(model, names, row))
        pin.updateGeometryPlacements(model, data, geometry, placements)
        for i in hand:
            g, placed_at = geometry.geometryObjects[i], placements.oMg[i]
            where = coal.Transform3s(placed_at.rotation, placed_at.translation)
            for j, (shape, pose) in enumerate(targets):
                gap = coal.distance(g.geometry, where, shape, pose, coal.DistanceRequest(),
                                    coal.DistanceResult())  # fmt: skip
                out[k, j] = min(out[k, j], gap)
    return out


def approach_clearance(item: Replay, truth: Problem) -> dict[str, float]:
    """The fingers' closest pass [mm] by the believed stick and by the true one (at its
    start pose) over the reach, up to the first touch (the palm is not counted)."""
    frames = item.record.frames
    assert frames is not None
    phases = frames["phase"]
    period = float(frames["period_s"])
    last = _last(phases, ("reach",))
    first = item.record.first_contact
    if first is not None and first["phase"] == "reach":
        last = min(last or 0, int(first["time_s"] / period) - 1)
    reach = [i for i, p in enumerate(phases) if p == "reach" and i <= (last or -1)]
    if not reach:
        return {}
    start = dataclasses.replace(item.truth, pose=np.asarray(frames["object"][0]))
    rows = np.asarray(frames["q"], dtype=float)[reach]
    gaps = clearances(truth, frames["joint_names"], rows, [item.believed, start])
    return {"believed_clearance_mm": 1e3 * float(gaps[:, 0].min()),
            "true_clearance_mm": 1e3 * float(gaps[:, 1].min())}  # fmt: skip


def measure(item: Replay, truth: Problem) -> dict[str, Any]:
    """What the replay shows (module docstring)."""
    record = item.record
    frames = record.frames
    assert frames is not None
    poses = np.asarray(frames["object"], dtype=float)
    phases = frames["phase"]
    period = float(frames["period_s"])
    start = poses[0, :3]
    first = record.first_contact
    out: dict[str, Any] = {
        "policy": item.policy,
        "u": item.u,
        "cause": record.cause,
        "believed_mm": (item.believed.pose[:3] * 1e3).round(1).tolist(),
        "true_mm": (item.truth.pose[:3] * 1e3).round(1).tolist(),
        # The top of the stick, believed and true [mm] (the centre plus half the length).
        "believed_top_mm": round(
            1e3 * (item.believed.pose[2] + (item.believed.length or 0) / 2), 1
        ),
        "true_top_mm": round(1e3 * (item.truth.pose[2] + (item.truth.length or 0) / 2), 1),
        "first_touch": first,
        "moved_before_closing": record.moved_before_closing,
        "ended_early": record.ended_early,
    }
    if first is not None:
        k = min(len(phases) - 1, int(first["time_s"] / period))
        width, palm = hand_at(truth, frames["joint_names"], frames["q"][k], item.grasp)
        out["aperture_at_touch_mm"] = 1e3 * width
        out["palm_from_grasp_mm"] = (1e3 * palm).round(0).tolist()
        height, gap = touch_height(truth, frames["joint_names"], frames["q"][k], poses[k],
                                   first["link"])  # fmt: skip
        out["touch_height_mm"] = 1e3 * height
        out["touch_gap_mm"] = 1e3 * gap
        out["stick_length_mm"] = 1e3 * (item.truth.length or 0.0)
    out.update(approach_clearance(item, truth))
    for label, names in (("reach", ("reach",)), ("squeeze", ("close", "squeeze")),
                         ("lift", ("lift",))):  # fmt: skip
        end = _last(phases, names)
        if end is not None:
            out[f"after_{label}"] = {
                "moved_mm": round(1e3 * float(np.linalg.norm(poses[end, :2] - start[:2])), 1),
                "z_mm": round(1e3 * float(poses[end, 2] - start[2]), 1),
                "tilt_deg": round(_tilt(poses[end]), 1),
            }
    return out


def policy_value(policy: str, belief: Belief, result: dict[str, Any]) -> float:
    """The ``u`` the study gave ``policy`` (the adaptive fallback as the shard says)."""
    assert belief.evidence is not None and belief.believed is not None
    if "fallback_from" in result:
        return FALLBACK_U
    safe = None
    if policy == "capped":
        from openup_ompl.study.geometry import HandSweep

        safe = HandSweep(belief.believed).largest_safe_u()
    return round(policy_u(policy, belief.evidence, belief.believed, safe), 9)


def run(args: argparse.Namespace, trial: int) -> tuple[Problem, list[Replay]]:
    """Rebuild ``trial``, replay each policy, and check every verdict against the shard."""
    committed = shard_trial(args.shards, args.family, args.error, trial)
    truth, belief, plan_seed = rebuild(args.family, args.error, trial, args.seed, args.mesh_dir)
    if plan_seed != committed["plan_seed"]:
        sys.exit(f"trial {trial}: plan seed {plan_seed} != the shard's {committed['plan_seed']}")
    if belief.believed is None:
        sys.exit(f"trial {trial}: perception refused the view ({belief.refusal})")
    offset = np.asarray(belief.offset) - np.asarray(committed["offset"])
    if np.max(np.abs(offset)) > 1e-9:
        sys.exit(f"trial {trial}: belief offset {belief.offset} != the shard's")
    replays = []
    assert belief.believed.object is not None and truth.object is not None
    for policy in args.policies:
        result = committed["results"][policy]
        u = policy_value(policy, belief, result)
        if not math.isclose(u, result["u"], abs_tol=1e-9):
            sys.exit(f"trial {trial}, policy {policy}: u {u} != the shard's {result['u']}")
        record = replay(truth, belief, plan_seed, u, args)
        if record is None:
            sys.exit(f"trial {trial}, policy {policy}: the plan failed (shard: {result})")
        judged = physics_trial(record.to_dict(False))
        print(f"trial {trial}, u = {u:g} ({policy}):")
        print(f"  shard:   held {result['held']}, {result['verdict']}")
        print(f"  rebuilt: held {judged['success']}, {judged['verdict']}")
        same = judged["success"] == result["held"] and judged["cause"] == result["cause"]
        if not args.full:
            same = same and judged["verdict"] == result["verdict"]
        if not same:
            sys.exit(
                f"trial {trial}, policy {policy}: the rebuilt verdict differs from the shard's"
            )
        grasp = belief.believed.grasp.translation
        replays.append(
            Replay(policy, u, record, result, belief.believed.object, truth.object, grasp)
        )
    return truth, replays


def _palm_d(scene: Any, model: pin.Model, names: list[str], q: np.ndarray) -> np.ndarray:
    """Algorithm 1's ``d`` (palm distance to the grasp over that at the start) per frame."""
    data = model.createData()
    palms = []
    for row in q:
        pin.framesForwardKinematics(model, data, _full(model, names, row))
        palms.append(np.array(data.oMf[scene.palm_frame_id].translation))
    goal = scene.grasp.translation
    distance = np.linalg.norm(np.array(palms) - goal, axis=1)
    return np.asarray(distance / distance[0])


def _panels(item: Replay, touch_d: float | None, d: np.ndarray) -> list[tuple[int, str]]:
    """``(frame, title)``: the approach where the other row first touched (or this row's
    own first touch), the end of the reach, the hand closed, the top of the lift."""
    frames = item.record.frames
    assert frames is not None
    phases, period = frames["phase"], float(frames["period_s"])
    first = item.record.first_contact
    panels = []
    if touch_d is not None:
        reach = [i for i, p in enumerate(phases) if p == "reach" and d[i] <= touch_d]
        if reach:
            at = reach[0]
            what = "no touch yet"
            if first is not None and first["time_s"] <= (at + 1.5) * period:
                what = f"touch: {first['link'].removeprefix('sdh_')}"
            panels.append((at, f"approach, d = {d[at]:.2f}\n{what}"))
    for names, title in ((("reach",), "end of reach"), (("close", "squeeze"), "hand closed"),
                         (("lift",), "top of lift")):  # fmt: skip
        k = _last(phases, names)
        if k is not None:
            panels.append((k, f"{title}\nt = {(k + 1) * period:.2f} s"))
    return panels


def _caption(item: Replay) -> str:
    """A row's second line: the first touch and what the reach did to the stick."""
    first = item.record.first_contact
    if first is None:
        return "the hand never touched the stick"
    where = "during the reach" if first["phase"] == "reach" else f"on {first['phase']}"
    text = f"first touch {where} ({first['link'].removeprefix('sdh_')}, d = {first['d']:.2f})"
    moved = item.record.moved_before_closing
    return (
        text
        + f"; by the end of the reach the stick moved {moved['mm']:.0f} mm / {moved['deg']:.0f} deg"
    )


def draw(trial: int, replays: list[Replay], out: Path, dpi: int = 120) -> Path:
    """The figure: one row per policy (module docstring), one view for every panel."""
    from openup_ompl.plan import PlanFile
    from openup_ompl.viz import storyboard as sb
    from openup_ompl.viz._geometry import placed, shape_mesh
    from openup_ompl.viz._mpl import _pyplot, _save
    from openup_ompl.viz._scene import PlanScene

    plt = _pyplot()
    scenes = []
    for item in replays:
        assert item.record.source is not None
        scenes.append(PlanScene.from_plan_file(PlanFile.from_dict(item.record.source, "rollout")))
    ds = []
    for item, scene in zip(replays, scenes, strict=True):
        frames = item.record.frames
        assert frames is not None
        q = np.asarray(frames["q"], dtype=float)
        ds.append(_palm_d(scene, scene.model, frames["joint_names"], q))
    touches = [r.record.first_contact for r in replays]
    early = [t["d"] for t in touches if t is not None and t["phase"] == "reach" and t["d"]]
    touch_d = max(early) if early else None
    rows = [_panels(item, touch_d, d) for item, d in zip(replays, ds, strict=True)]
    columns = max(len(r) for r in rows)
    stick = replays[0].truth
    centre = stick.pose[:3] + np.array([0.0, 0.0, 0.04])
    half = 0.17
    low, high = centre - half, centre + half
    direction = scenes[0].view_direction()
    fig = plt.figure(figsize=(2.9 * columns, 3.5 * len(rows) + 0.6))
    grid = fig.add_gridspec(len(rows), columns)
    grid.update(left=0.01, right=0.99, top=0.80, bottom=0.01, wspace=0.02, hspace=0.42)
    fig.suptitle(
        f"Study trial {trial} (seed 2, LWA3-SDH, thin stick, perceived pose): the same plan"
        " seed, belief and truth, planned with each u", fontsize=12, y=0.985,
    )  # fmt: skip
    believed = replays[0].believed
    axis = believed.placement.rotation[:, 2] * (believed.length or 0.0) / 2
    ends = np.array([believed.pose[:3] - axis, believed.pose[:3] + axis])
    error = 1e3 * (stick.pose[:2] - believed.pose[:2])
    tops = [1e3 * (s.pose[2] + (s.length or 0.0) / 2) for s in (stick, believed)]
    fig.text(0.5, 0.935, f"orange: the true stick as simulated; dashed: its axis as believed"
             f" (true - believed: {error[0]:+.0f}, {error[1]:+.0f} mm in x, y; top at"
             f" {tops[0]:.0f} mm, believed {tops[1]:.0f} mm)",
             ha="center", fontsize=9.5, color="dimgrey")  # fmt: skip
    for r, (item, scene, panels) in enumerate(zip(replays, scenes, rows, strict=True)):
        robot = sb._Robot(scene, sb.StoryboardOptions())
        frames = item.record.frames
        assert frames is not None
        q = np.asarray(frames["q"], dtype=float)
        poses = np.asarray(frames["object"], dtype=float)
        obstacles = [s for s in scene.shapes if s.name != scene.object_name]
        target = next(s for s in scene.shapes if s.name == scene.object_name)
        for c, (k, title) in enumerate(panels):
            ax = fig.add_subplot(grid[r, c], projection="3d")
            layers: list[tuple[np.ndarray, tuple[float, ...]]] = []
            moved = dataclasses.replace(target, pose=poses[k])
            for shape in [*obstacles, moved]:
                clipped = sb._clipped(shape, low, high)
                if clipped is not None:
                    mesh = shape_mesh(clipped, max_edge=0.02)
                    color = sb.OBJECT_COLOR if shape is moved else sb.OBSTACLE_COLOR
                    layers.append((sb._triangles([placed(mesh, clipped.placement)]), color))
            arm, hand = robot.meshes_at(q[k], fine=True)
            layers += [(sb._triangles(arm), sb.ARM_COLOR), (sb._triangles(hand), sb.HAND_COLOR)]
            sb._draw(ax, layers, low, high, direction, zoom=1.25, strict=True)
            ax.plot(*ends.T, color="black", ls="--", lw=1.0, zorder=5)
            ax.set_title(title, fontsize=9.5, pad=0)
        top = grid[r, 0].get_position(fig).y1
        name = "" if item.policy == f"{item.u:g}" else f" ({item.policy})"
        fig.text(0.01, top + 0.085, f"u = {item.u:g}{name}: {item.shard['verdict']}",
                 fontsize=10, weight="bold", va="bottom")  # fmt: skip
        fig.text(0.01, top + 0.065, _caption(item), fontsize=9, va="bottom")
    return _save(fig, out, dpi)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--trial", type=int, nargs="+", default=[18], help="trial indices")
    parser.add_argument("--family", default="lwa3_sdh-thin")
    parser.add_argument("--error", default="perceived")
    parser.add_argument("--policies", nargs="+", default=["0.3", "1"])
    parser.add_argument("--seed", type=int, default=2, help="the study's seed")
    parser.add_argument("--planner", default="ikbirrt")
    parser.add_argument("--time", type=float, default=5.0, help="time limit per plan [s]")
    parser.add_argument("--shards", type=Path, default=SHARDS)
    parser.add_argument("--mesh-dir", type=Path, default=Path("study_meshes").resolve())
    parser.add_argument(
        "--full", action="store_true",
        help="run the rollouts to their end (no early end; then the verdict's cause, not"
        " its numbers, must match the shard's)",
    )  # fmt: skip
    parser.add_argument("--out", type=Path, default=None, help="the figure (first trial)")
    parser.add_argument("--json", type=Path, default=None, help="the measurements")
    args = parser.parse_args()
    rows = []
    for i, trial in enumerate(args.trial):
        truth, replays = run(args, trial)
        for item in replays:
            row = {"trial": trial, **measure(item, truth)}
            rows.append(row)
            print(json.dumps(row))
        if i == 0 and args.out is not None:
            print(f"wrote {draw(trial, replays, args.out)}")
    if args.json is not None:
        args.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
