"""Pictures of what each robot's fingers present to MuJoCo: the physics world's collision
geometry at the end of the squeeze of its demo grasp (plan seed 1, the can at its nominal
pose), rendered offscreen by MuJoCo (``MUJOCO_GL=egl``, headless).

Colours: orange, a contact pad (``[physics] pads``, physics only); grey, URDF collision
geometry that meets the object (the planner's geometry, as MuJoCo loads it); blue and
translucent, the can. Hidden: the obstacles, and the URDF geometry that a pad replaces
(it meets only the fixed obstacles). Panels without pads
(``PhysicsOptions(pads=False)``) show the planner's geometry as MuJoCo meets it; the
Panda's with its robot file's pads; the Allegro's last one with the candidate fingertips
of ``benchmarks/contact/allegro_menagerie_tips.toml`` (measured, not shipped).

Run (about a minute on one core)::

    MUJOCO_GL=egl python benchmarks/contact_geometry.py --out docs
"""

from __future__ import annotations

import argparse
import os
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

os.environ.setdefault("MUJOCO_GL", "egl")
sys.path.insert(0, str(Path(__file__).resolve().parent))

from physics_fingertips import candidate_pads  # noqa: E402

import openup_ompl as ou  # noqa: E402
from openup_ompl.physics import PhysicsOptions, Rollout  # noqa: E402
from openup_ompl.physics.pads import PAD  # noqa: E402
from openup_ompl.physics.world import OBJECT, ROBOT  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
ALLEGRO_PADS = ROOT / "benchmarks" / "contact" / "allegro_menagerie_tips.toml"
#: Per robot: the scene, the pads of the panels with pads (None: the robot file's), and
#: the panels: (with pads, azimuth, elevation [deg], distance [m], look-at offset from the
#: palm along its approach [m], title).
Panel = tuple[bool, float, float, float, float, str]
ROBOTS: dict[str, tuple[str, Path | None, list[Panel]]] = {
    "panda": ("panda_can.toml", None, [
        (False, 160.0, -10.0, 0.16, 0.10, "planning geometry (pads=False)"),
        (True, 160.0, -10.0, 0.16, 0.10, "physics: the robot file's pads"),
        (True, 90.0, -10.0, 0.16, 0.10, "physics: pads, along the closing axis"),
    ]),
    "lwa3_sdh": ("lwa3_sdh_can.toml", None, [
        (False, 200.0, -30.0, 0.40, 0.10, "planning = physics geometry (no pads)"),
        (False, 180.0, -89.0, 0.40, 0.10, "from above, along the can's axis"),
    ]),
    "ur5_allegro": ("ur5_allegro_can.toml", ALLEGRO_PADS, [
        (False, 120.0, -30.0, 0.30, 0.06, "planning = physics geometry (no pads)"),
        (False, 90.0, 89.0, 0.30, 0.06, "from below, along the can's axis"),
        (True, 120.0, -30.0, 0.30, 0.06, "candidate: Menagerie's fingertips (not shipped)"),
    ]),
}  # fmt: skip
PAD_RGBA = (1.0, 0.55, 0.1, 1.0)
MEETS_RGBA = (0.72, 0.72, 0.72, 1.0)
OBSTACLES_ONLY_RGBA = (0.0, 0.0, 0.0, 0.0)  # hidden: it would z-fight with the pads
CAN_RGBA = (0.3, 0.5, 0.9, 0.35)


def demo_plan(scene: Path, pads: tuple[Any, ...] | None) -> ou.Plan:
    """The scene's demo plan (seed 1), its robot carrying ``pads`` (None: its own)."""
    problem = ou.load_scene(scene)
    if pads is not None:
        problem.robot.spec = replace(problem.robot.spec, pads=pads)
    return ou.GraspPlanningSetup(problem).solve(time_limit=30.0, seed=1)


def squeezed(plan: ou.Plan, use_pads: bool) -> tuple[Any, Any, Any]:
    """The plan's physics world and its state at the end of the squeeze: ``(world, data,
    (palm position, approach direction))``."""
    import mujoco

    problem = plan.problem
    rollout = Rollout(plan, PhysicsOptions(pads=use_pads))
    record = rollout.run((0.0, 0.0, 0.0), frames=True)
    assert record.frames is not None
    last = max(i for i, p in enumerate(record.frames["phase"]) if p == "squeeze")
    world = rollout.world
    data = mujoco.MjData(world.model)
    data.qpos[world.qpos] = record.frames["q"][last]
    x, y, z, qx, qy, qz, qw = record.frames["object"][last]
    data.qpos[world.object_qpos : world.object_qpos + 7] = [x, y, z, qw, qx, qy, qz]
    mujoco.mj_forward(world.model, data)
    approach = data.xmat[world.palm_body].reshape(3, 3) @ np.asarray(problem.robot.spec.approach)
    return world, data, (data.xpos[world.palm_body].copy(), approach)


def colour(world: Any) -> None:
    """Colour the world's geoms by what they meet (module docstring); hide the rest."""
    model = world.model
    can = world.object_geom
    for g in range(model.ngeom):
        kind = world.geom_kind[g]
        if g == can:
            model.geom_rgba[g] = CAN_RGBA
        elif kind == ROBOT:
            meets = (model.geom_contype[g] & model.geom_conaffinity[can]) or (
                model.geom_contype[can] & model.geom_conaffinity[g]
            )
            if model.geom(g).name.startswith(PAD):
                model.geom_rgba[g] = PAD_RGBA
            else:
                model.geom_rgba[g] = MEETS_RGBA if meets else OBSTACLES_ONLY_RGBA
        elif kind != OBJECT:
            model.geom_rgba[g] = (0.0, 0.0, 0.0, 0.0)  # obstacles hidden: the hand in view
    model.vis.headlight.ambient[:] = 0.45
    model.vis.headlight.diffuse[:] = 0.6


def render(world: Any, data: Any, palm: tuple[Any, Any], view: Panel) -> Any:
    """An offscreen picture (RGB array) of the hand."""
    import mujoco

    colour(world)
    _, azimuth, elevation, distance, ahead, _ = view
    camera = mujoco.MjvCamera()
    camera.lookat[:] = palm[0] + ahead * palm[1]
    camera.azimuth, camera.elevation, camera.distance = azimuth, elevation, distance
    world.model.vis.global_.offwidth = max(world.model.vis.global_.offwidth, 640)
    with mujoco.Renderer(world.model, 420, 560) as renderer:
        renderer.update_scene(data, camera)
        return renderer.render()


def figure(robot: str, out: Path) -> Path:
    """The robot's panels in ``out/contact_<robot>.png``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    scene, pad_file, panels = ROBOTS[robot]
    problem = ou.load_scene(ROOT / "scenes" / scene)
    pads = candidate_pads(problem.robot, str(pad_file)) if pad_file else None
    fig, axes = plt.subplots(1, len(panels), figsize=(4.2 * len(panels), 4.0))
    plan = demo_plan(ROOT / "scenes" / scene, pads)
    worlds = {}
    for ax, panel in zip(axes, panels, strict=True):
        use_pads = panel[0]
        if use_pads not in worlds:
            worlds[use_pads] = squeezed(plan, use_pads)
        ax.imshow(render(*worlds[use_pads], panel))
        ax.set_title(panel[-1], fontsize=9)
        ax.axis("off")
    legend = [Patch(color=PAD_RGBA, label="contact pad (physics only)"),
              Patch(color=MEETS_RGBA, label="URDF collision geometry, meets the can"),
              Patch(color="white", ec="0.5",
                    label="hidden: URDF geometry under a pad (fixed obstacles only)"),
              Patch(color=CAN_RGBA[:3], alpha=0.5, label="the can")]  # fmt: skip
    fig.legend(handles=legend, loc="lower center", ncol=2, fontsize=8)
    fig.suptitle(f"{robot}: what the fingers present to MuJoCo, the demo grasp at the end "
                 "of the squeeze (plan seed 1)", fontsize=10)  # fmt: skip
    fig.tight_layout(rect=(0, 0.1, 1, 0.96))
    path = out / f"contact_{robot}.png"
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(ROOT / "docs"), help="directory of the PNGs")
    parser.add_argument("--robot", nargs="+", default=list(ROBOTS), choices=list(ROBOTS))
    args = parser.parse_args()
    for robot in args.robot:
        print(figure(robot, Path(args.out)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
