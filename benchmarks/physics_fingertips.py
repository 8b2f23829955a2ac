"""Fingertip contact check: where a robot's fingers touch a displaced can, do they touch
it with a face or with a box's edge, do the contact normals follow the can's surface, and
is the can held?

The Panda's URDF fingertip boxes met a can 2 cm across them with their vertical edges,
and MuJoCo let the can creep out between the two edge contacts and drop
(``benchmarks/physics_pads.py``). This script checks any robot the same way: per plan (a
planning seed) the nominal can, then the can displaced by +-delta along each palm axis
whose projection on the table is at least half long (two of the three for every demo
grasp), executed in physics. Every robot-can contact carrying a normal force (from
0.1 N) from the closing to the end of the hold, every 10th step, is sampled: the angle of
its normal from the can's own normal there (radial on its side; contacts within 2 mm of
a cap's plane are left out, where an edge meets the rim and the normal is free), and its
angle from the nearest face normal of the finger's box (over 20 deg: the box touches with
an edge or a corner; 0 for spheres and capsules).

Each row: held counts with Wilson 95 % intervals, the largest angle from the can's
normal and how many side contacts exceed 20 deg, the largest angle off a box face and how
many contacts exceed 20 deg, the links that touched with an edge, the largest creep of a
held can in the hand [mm] (the record's ``in_hand``) and the outcomes seen. ``--pads``
tries candidate pads without editing the robot file; ``--no-pads`` runs the URDF's
geometry alone.

Run (about two minutes on one busy core for the defaults: 2 scenes x 3 plans x 9)::

    python benchmarks/physics_fingertips.py
    python benchmarks/physics_fingertips.py \
        --scene benchmarks/contact/panda_can_between_blocks.toml \
        --deltas 0.01 0.015 0.02 0.03 --no-pads
    python benchmarks/physics_fingertips.py --scene scenes/ur5_allegro_can.toml \
        --deltas 0.02 0.03 --pads benchmarks/contact/allegro_menagerie_tips.toml
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from collections import defaultdict
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

sys.path.insert(0, str(Path(__file__).resolve().parent))

import _common  # noqa: E402
from physics_pads import interval  # noqa: E402

import openup_ompl as ou  # noqa: E402
import openup_ompl.physics.rollout as rollout_module  # noqa: E402
from openup_ompl.physics import PhysicsOptions, Rollout  # noqa: E402
from openup_ompl.physics.monitor import Monitor  # noqa: E402
from openup_ompl.physics.world import ROBOT  # noqa: E402
from openup_ompl.robot_file import RobotSpec  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
SCENES = [ROOT / "scenes" / "lwa3_sdh_can.toml", ROOT / "scenes" / "ur5_allegro_can.toml"]
#: Phases whose contacts are checked, the steps between samples, the deviation [deg]
#: counted as turned, and the band [m] around a rim where either normal is the can's.
PHASES = ("close", "squeeze", "lift", "hold")
EVERY = 10
TURNED = 20.0
RIM = 0.002
#: The normal force [N] from which a contact is sampled (grazing ones carry none).
LOADED = 0.1


class NormalMonitor(Monitor):
    """The rollout's monitor, also sampling every robot-can contact: its link, the angle
    [deg] of its normal from the can's (:func:`_from_can`) and from the nearest face of
    the finger's box (:func:`_off_face`), in :attr:`samples`."""

    #: The monitor made last (the rollout's).
    last: NormalMonitor | None = None

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.samples: list[tuple[str, float | None, float]] = []
        NormalMonitor.last = self

    def step(self) -> None:
        super().step()
        if self.phase in PHASES and self.steps % EVERY == 0 and self.sim.ncon:
            self._sample()

    def _sample(self) -> None:
        import mujoco

        world, sim = self.world, self.sim
        force = np.zeros(6)
        for i in range(sim.ncon):
            a, b = (int(g) for g in sim.contact.geom[i])
            if world.object_geom not in (a, b):
                continue
            other = b if a == world.object_geom else a
            if world.geom_kind[other] != ROBOT:
                continue
            mujoco.mj_contactForce(world.model, sim, i, force)
            if force[0] < LOADED:
                continue
            normal = sim.contact.frame[i][:3]
            self.samples.append((
                world.geom_link[other], _from_can(world, sim, sim.contact.pos[i], normal),
                _off_face(world.model, sim, other, normal),
            ))  # fmt: skip


def _from_can(world: Any, sim: Any, point: np.ndarray, normal: np.ndarray) -> float | None:
    """Angle [deg] of a contact normal at ``point`` on the can's side from the can's own
    normal there (the radial direction); ``None`` within :data:`RIM` of a cap's plane (on
    a cap or its rim, where an edge meets the rim's edge and the normal is free)."""
    centre = sim.xpos[world.object_body]
    axis = sim.xmat[world.object_body].reshape(3, 3)[:, 2]
    along = float((point - centre) @ axis)
    radial = point - centre - along * axis
    radial = radial / max(float(np.linalg.norm(radial)), 1e-12)
    if abs(along) < world.object_shape.length / 2 - RIM:
        return _angle(normal, radial)
    return None


def _off_face(model: Any, sim: Any, geom: int, normal: np.ndarray) -> float:
    """Angle [deg] of ``normal`` from the nearest face normal of box ``geom`` (an edge or
    a corner contact turns it off every face); 0 for other shapes."""
    import mujoco

    if model.geom_type[geom] != mujoco.mjtGeom.mjGEOM_BOX:
        return 0.0
    axes = sim.geom_xmat[geom].reshape(3, 3)
    return min(_angle(normal, axes[:, k]) for k in range(3))


def _angle(normal: np.ndarray, reference: np.ndarray) -> float:
    """Angle [deg] between two lines (unsigned)."""
    return float(np.degrees(np.arccos(min(1.0, abs(float(normal @ reference))))))


def directions(problem: ou.Problem) -> dict[str, np.ndarray]:
    """Unit table vectors along the palm axes whose table projection is at least half long."""
    rotation = pin.XYZQUATToSE3(np.asarray(problem.grasp_pose)).rotation
    found = {}
    for k, name in enumerate("xyz"):
        v = rotation[:, k].copy()
        v[2] = 0.0
        if np.linalg.norm(v) >= 0.5:
            found[f"palm {name}"] = v / np.linalg.norm(v)
    return found


def candidate_pads(robot: ou.Robot, path: str) -> tuple[Any, ...]:
    """The pads of ``path`` (a TOML file with a ``[physics]`` table), read as the robot
    file's own would be (checked the same way)."""
    text = robot.spec.path.read_text().split("[physics]")[0] + "\n" + Path(path).read_text()
    with tempfile.TemporaryDirectory() as tmp:
        copy = Path(tmp) / robot.spec.path.name
        copy.write_text(text)
        return RobotSpec.from_file(copy).pads


def run_scene(
    scene: str, seeds: int, deltas: list[float], pads: bool, candidate: str | None = None
) -> list[dict[str, Any]]:
    """Every trial of one scene: per plan the nominal can, then each axis and signed
    delta; with ``candidate``, the robot's pads replaced by those of that file."""
    problem = ou.load_scene(scene)
    if candidate is not None:
        robot = problem.robot
        robot.spec = replace(robot.spec, pads=candidate_pads(robot, candidate))
    setup = ou.GraspPlanningSetup(problem)
    trials = []
    rollout_module.Monitor = NormalMonitor  # type: ignore[misc]
    try:
        for seed in range(1, seeds + 1):
            plan = setup.solve(time_limit=10.0, seed=seed)
            rollout = Rollout(plan, PhysicsOptions(pads=pads))
            trials.append(_trial(rollout, seed, "-", np.zeros(3), 0.0))
            for axis, direction in directions(problem).items():
                for delta in deltas:
                    for sign in (-1.0, 1.0):
                        trials.append(_trial(rollout, seed, axis, direction, sign * delta))
    finally:
        rollout_module.Monitor = Monitor  # type: ignore[misc]
    return trials


def _trial(
    rollout: Rollout, seed: int, axis: str, direction: np.ndarray, offset: float
) -> dict[str, Any]:
    """One rollout with the can ``offset`` [m] along ``direction``; what its contacts
    showed."""
    dx, dy = (offset * direction[:2]).tolist()
    record = rollout.run((dx, dy, 0.0), frames=False)
    assert NormalMonitor.last is not None
    samples = NormalMonitor.last.samples
    edges = sorted({link for link, _, off in samples if off > TURNED})
    return {
        "seed": seed, "axis": axis, "offset": offset, "dx": dx, "dy": dy,
        "outcome": record.cause or "held", "contacts": len(samples),
        "side": sum(s[1] is not None for s in samples),
        "from_can": sum(s[1] is not None and s[1] > TURNED for s in samples),
        "from_can_deg": max((s[1] for s in samples if s[1] is not None), default=0.0),
        "off_face_deg": max((s[2] for s in samples), default=0.0),
        "off_face": sum(s[2] > TURNED for s in samples), "edge_links": edges,
        "creep_mm": record.in_hand["mm"],
    }  # fmt: skip


def table(trials: list[dict[str, Any]]) -> str:
    """Markdown table: one row per scene, axis and |offset|."""
    groups: dict[tuple[str, str, float], list[dict[str, Any]]] = defaultdict(list)
    for t in trials:
        groups[(t["scene"], t["axis"], abs(t["offset"]))].append(t)
    rows = []
    for (scene, axis, size), chosen in sorted(groups.items()):
        held = [t for t in chosen if t["outcome"] == "held"]
        contacts = sum(t["contacts"] for t in chosen)
        links = sorted({link.removeprefix("sdh_") for t in chosen for link in t["edge_links"]})
        rows.append([
            scene, axis, f"{'+-' if size else ''}{size * 100:g} cm",
            interval(len(held), len(chosen)),
            f"{max(t['from_can_deg'] for t in chosen):.0f}",
            f"{sum(t['from_can'] for t in chosen)}/{sum(t['side'] for t in chosen)}",
            f"{max(t['off_face_deg'] for t in chosen):.0f}",
            f"{sum(t['off_face'] for t in chosen)}/{contacts}", ", ".join(links) or "-",
            f"{max(t['creep_mm'] for t in held):.1f}" if held else "-",
            ", ".join(sorted({t["outcome"] for t in chosen})),
        ])  # fmt: skip
    header = ["scene", "displaced along", "error", "held", "normal from the can's [deg]",
              f"side contacts > {TURNED:g} deg from the can's",
              "normal off a box face [deg]", f"contacts > {TURNED:g} deg off a face",
              "links touching with an edge", "held: creep in hand [mm]", "outcomes"]  # fmt: skip
    return _common.markdown_table(header, rows)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", nargs="+", default=[str(s) for s in SCENES])
    parser.add_argument("--seeds", type=int, default=3, help="plans (seeds 1..N)")
    parser.add_argument("--deltas", type=float, nargs="+", default=[0.01, 0.015])
    parser.add_argument("--no-pads", action="store_true", help="PhysicsOptions(pads=False)")
    parser.add_argument(
        "--pads",
        default=None,
        help="a TOML file whose [physics] pads replace the robot's (a candidate)",
    )
    parser.add_argument("--json", default=None, help="also write the trials as JSON here")
    args = parser.parse_args()
    trials = []
    for scene in args.scene:
        for t in run_scene(scene, args.seeds, args.deltas, not args.no_pads, args.pads):
            trials.append({"scene": Path(scene).stem, **t})
    pads = "off" if args.no_pads else args.pads or "as the robot files give"
    print(f"{args.seeds} plans; pads {pads}")
    print(table(trials))
    print(_common.machine_line(_common.machine_info()))
    _common.write_json(args.json, {"machine": _common.machine_info(), "trials": trials})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
