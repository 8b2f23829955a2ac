"""Why the law costs the LWA3 more than the fixed `w`: the hand's shape, passage by passage.

``bench_speed.py`` splits the law's price into the search's size (motions checked) and the
law's own work per motion; on the LWA3 the law's search is 1.15-1.2x the fixed `w`'s. This
script looks for the reason in the passages the two searches find. It plans every suite
problem with ``ikbirrt`` (``--seeds`` seeds, from ``--first-seed``), once with the law and
once with the hand fixed at `w`, keeps the unsimplified paths (the passage each search
found), and checks every row of each path again with the other hand, without margin
(contact only): the law's hand at that row's ``d`` on `w`'s path, `w` on the law's.

It prints, per problem, how many of one hand's paths the other hand cannot follow, the
``d`` of the first row where it collides and what it hits; then, per robot, the extents of
the hands in the palm frame: how far the fingers reach ahead of the palm (along the
approach) and across. It draws ``law_shape.png``: the hands' silhouettes in the palm frame
(law plateau, at ``mga``, `w`) and one row of a `w` path where the law's hand collides,
with either hand.

    python benchmarks/law_shape.py                     # about 2 min on 2 idle cores
    python benchmarks/law_shape.py --robots lwa3_sdh --seeds 20 --out shape.png
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
from ompl import util as ou

sys.path.insert(0, str(Path(__file__).resolve().parent))

import _common  # noqa: E402

import openup_ompl as oo  # noqa: E402
from openup_ompl._model import moved_by  # noqa: E402
from openup_ompl.benchmark import default_problems_dir  # noqa: E402
from openup_ompl.collision import CollisionWorld  # noqa: E402
from openup_ompl.viz._geometry import coal_mesh, placed  # noqa: E402

ROBOTS = ("lwa3_sdh", "panda", "ur5_allegro")
#: The two searches compared: the law, and the hand fixed at `w`.
HANDS = ("law", "w")


def finger_geometries(robot: oo.Robot) -> list[int]:
    """Indices of the collision geometries of the links a hand joint moves."""
    return np.flatnonzero(moved_by(robot.model, robot.collision_model, robot.hand_joints)).tolist()


def finger_points(robot: oo.Robot, arm: np.ndarray, hand: np.ndarray) -> list[np.ndarray]:
    """Per finger geometry, its mesh's vertices in the palm frame [m] (``hand`` driven)."""
    model, geometry = robot.model, robot.collision_model
    data, placements = model.createData(), geometry.createData()
    pin.framesForwardKinematics(model, data, robot.full_q(arm, hand))
    pin.updateGeometryPlacements(model, data, geometry, placements)
    palm = data.oMf[robot.palm_frame_id]
    points = []
    for i in finger_geometries(robot):
        mesh = coal_mesh(geometry.geometryObjects[i].geometry, max_edge=0.01)
        if mesh is not None:
            world = placed(mesh, placements.oMg[i])[0]
            points.append((world - palm.translation) @ palm.rotation)
    return points


def extents(robot: oo.Robot, arm: np.ndarray, hand: np.ndarray) -> tuple[float, float]:
    """How far the fingers reach ahead of the palm along the approach, and their largest
    span across it [m]."""
    approach = np.asarray(robot.spec.approach, dtype=float)
    points = np.concatenate(finger_points(robot, arm, hand))
    ahead = points @ approach
    across = points - np.outer(ahead, approach)
    span = max(np.ptp(across[:, k]) for k in range(3))
    return float(ahead.max()), float(span)


def _driven(law: oo.HandLaw, d: float) -> np.ndarray:
    return np.asarray(law(d), dtype=float)


def cross_check(path: Path, seeds: range) -> dict[str, Any]:
    """Plan ``path``'s problem with either hand and follow each path with the other."""
    problem = oo.load_scene(path)
    setups = {
        "law": oo.GraspPlanningSetup(problem),
        "w": oo.GraspPlanningSetup(problem, fixed_hand="w"),
    }
    checker, law = setups["law"].checker, setups["law"].law
    contact = CollisionWorld(problem, padding=0.0)
    blocked: dict[str, list[dict[str, Any]]] = {hand: [] for hand in HANDS}
    for hand, setup in setups.items():
        for seed in seeds:
            plan = setup.solve(seed=seed, simplify=False)
            for row, arm in enumerate(plan.arm_path):
                d = checker.normalized_distance(arm)
                other = law.w if hand == "law" else _driven(law, d)
                q = problem.robot.full_q(arm, other)
                if contact.in_collision(q):
                    blocked[hand].append(
                        {
                            "seed": seed,
                            "row": row,
                            "d": d,
                            "arm": arm.copy(),
                            "pairs": contact.colliding_pairs(q),
                            "plan": plan,
                        }
                    )
                    break
    return {
        "problem": problem,
        "law": law,
        "name": path.stem,
        "seeds": len(seeds),
        "blocked": blocked,
    }


def _what(pairs: list[tuple[str, str]], fingers: set[str]) -> list[str]:
    """``finger link → what it touches`` for the pairs a finger is in."""
    hits = []
    for first, second in pairs:
        finger, other = (first, second) if first in fingers else (second, first)
        if finger in fingers:
            hits.append(f"{finger.removesuffix('_0')} → {other.removeprefix('env/')}")
    return hits


def problem_rows(results: list[dict[str, Any]]) -> list[list[object]]:
    rows: list[list[object]] = []
    for r in results:
        robot = r["problem"].robot
        fingers = {robot.collision_model.geometryObjects[i].name for i in finger_geometries(robot)}
        cells: list[object] = [f"`{robot.name}`", r["name"]]
        for hand in ("w", "law"):  # the paths of w, with the law's hand; then the reverse
            blocked = r["blocked"][hand]
            hits = Counter(h for b in blocked for h in _what(b["pairs"], fingers))
            cells += [
                f"{len(blocked)} / {r['seeds']}",
                " ".join(f"{b['d']:.2f}" for b in blocked) or "-",
                ", ".join(f"{h} ({n})" if n > 1 else h for h, n in hits.most_common(2)) or "-",
            ]
        rows.append(cells)
    return rows


def extent_rows(hands: list[tuple[oo.Robot, oo.HandLaw]]) -> list[list[object]]:
    rows: list[list[object]] = []
    for robot, law in hands:
        arm = np.asarray(robot.spec.home, dtype=float)
        hands = {
            "c": law.c,
            "plateau (d = 1)": _driven(law, 1.0),
            "at mga": _driven(law, law.mga),
            "b": law.b,
            "w": law.w,
        }
        cells: list[object] = [f"`{robot.name}`", f"{law.u:g}"]
        for hand in hands.values():
            ahead, span = extents(robot, arm, np.asarray(hand, dtype=float))
            cells.append(f"{ahead * 100:.1f} / {span * 100:.1f}")
        rows.append(cells)
    return rows


def _silhouette(ax: Any, robot: oo.Robot, hand: np.ndarray, color: str, label: str) -> None:
    """The fingers' outline seen along the palm's y axis (x across, the approach up)."""
    from matplotlib.collections import PolyCollection

    arm = np.asarray(robot.spec.home, dtype=float)
    polygons = []
    for points in finger_points(robot, arm, hand):
        xz = points[:, [0, 2]]
        polygons.append(xz[_hull(xz)])
    ax.add_collection(
        PolyCollection(polygons, facecolors=color, edgecolors=color, alpha=0.35, label=label)
    )


def _hull(points: np.ndarray) -> np.ndarray:
    """Indices of the 2-D convex hull of ``points``, counter-clockwise."""
    from scipy.spatial import ConvexHull

    return ConvexHull(points).vertices


def plot(results: list[dict[str, Any]], out: Path) -> Path:
    """Silhouettes of the LWA3's hands, and one blocked row of a `w` path in close-up."""
    from openup_ompl.viz._mpl import _pyplot, _save
    from openup_ompl.viz._scene import PlanScene
    from openup_ompl.viz.storyboard import (
        ARM_COLOR,
        GRASP_COLOR,
        HAND_COLOR,
        StoryboardOptions,
        _draw,
        _environment,
        _Robot,
        _triangles,
        closeup_bounds,
    )

    plt = _pyplot()
    fig = plt.figure(figsize=(14.0, 5.2))
    grid = fig.add_gridspec(1, 3, width_ratios=[1.0, 1.2, 1.2], wspace=0.05)
    grid.update(left=0.06, right=0.99, top=0.80, bottom=0.10)
    ax = fig.add_subplot(grid[0, 0])
    robot, law = results[0]["problem"].robot, results[0]["law"]
    for hand, color, label in (
        (law.w, "C0", "fixed w"),
        (_driven(law, 1.0), "C3", f"law's plateau (u = {law.u:g})"),
    ):
        _silhouette(ax, robot, np.asarray(hand, dtype=float), color, label)
    ax.axhline(0.0, color="0.3", lw=0.8)
    ax.text(-0.15, 0.003, "palm face", fontsize=8, color="0.3")
    ax.autoscale_view()
    ax.set_aspect("equal")
    ax.set_xlabel("across the palm, x [m]")
    ax.set_ylabel("ahead of the palm, along the approach [m]")
    ax.set_title(f"{robot.name}: the fingers seen from the side", fontsize=11)
    ax.legend(loc="upper center", fontsize=8, ncols=2, bbox_to_anchor=(0.5, -0.22))
    ax.grid(alpha=0.3)

    case = _shown_case(results, robot.name, law.mga)
    if case is not None:
        r, blocked = case
        scene = PlanScene.from_plan(blocked["plan"], r["name"])
        drawn = _Robot(scene, StoryboardOptions(geometry="collision"))
        names = [g.name for g in drawn.geometry.geometryObjects]
        touching = {name for pair in blocked["pairs"] for name in pair}
        q = robot.full_q(blocked["arm"], law.w)
        for column, (hand, title) in enumerate(
            (
                (
                    _driven(law, blocked["d"]),
                    f"the law's hand (d = {blocked['d']:.2f}): in contact",
                ),
                (np.asarray(law.w, dtype=float), "the fixed w: free"),
            ),
            start=1,
        ):
            q[robot.hand_idx] = hand
            layers = {"arm": [], "hand": [], "contact": []}
            for i, world in enumerate(drawn.placed_at(q, fine=True)):
                if world is None:
                    continue
                kind = "arm"
                if drawn.is_hand[i]:
                    kind = "contact" if column == 1 and names[i] in touching else "hand"
                layers[kind].append(world)
            low, high = closeup_bounds(_palm(robot, q), layers["hand"] + layers["contact"], 1.5)
            panel = fig.add_subplot(grid[0, column], projection="3d")
            _draw(
                panel,
                [
                    *_environment(scene, low, high),
                    (_triangles(layers["arm"]), ARM_COLOR),
                    (_triangles(layers["hand"]), HAND_COLOR),
                    (_triangles(layers["contact"]), GRASP_COLOR),
                ],
                low,
                high,
                scene.view_direction(),
                strict=True,
            )
            panel.set_title(
                f"{r['name']}, row {blocked['row']} of w's path (seed {blocked['seed']})\n{title}",
                fontsize=10,
            )
    fig.suptitle(
        f"{robot.name}: the law's reach hand against the fixed w"
        + ("" if case is None else ", on a passage w found"),
        fontsize=12,
    )
    return _save(fig, out, 120)


#: The problems whose blocked rows the figure prefers, most telling first.
SHOWN = ("shelf_small", "table_under_pick", "narrow_passage", "cage")


def _shown_case(
    results: list[dict[str, Any]], robot: str, mga: float
) -> tuple[dict[str, Any], dict[str, Any]] | None:
    """A row of a `w` path where the law's hand (on its plateau) collides."""
    cases = [
        (r, b)
        for r in results
        if r["problem"].robot.name == robot
        for b in r["blocked"]["w"]
        if b["d"] > mga
    ]
    order = {name: k for k, name in enumerate(SHOWN)}
    cases.sort(key=lambda case: order.get(case[0]["name"], len(SHOWN)))
    return cases[0] if cases else None


def _palm(robot: oo.Robot, q: np.ndarray) -> np.ndarray:
    data = robot.model.createData()
    return robot.palm_placement(data, q).translation


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", nargs="+", default=list(ROBOTS), choices=ROBOTS)
    parser.add_argument("--seeds", type=int, default=10, help="plans per problem and hand (10)")
    parser.add_argument("--first-seed", type=int, default=16, help="first seed (default 16)")
    parser.add_argument("--out", type=Path, default=Path("law_shape.png"), help="figure (PNG)")
    args = parser.parse_args(argv)
    if args.seeds < 1 or args.first_seed < 1:
        parser.error(f"--seeds and --first-seed must be >= 1, got {args.seeds}, {args.first_seed}")
    ou.setLogLevel(ou.LogLevel.LOG_NONE)
    print(_common.machine_line(_common.machine_info()))
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    results = []
    for robot in args.robots:
        for path in sorted(default_problems_dir(robot).glob("*.toml")):
            results.append(cross_check(path, seeds))
            print(f"  {robot} {path.stem}", file=sys.stderr)
    print()
    print(
        "Paths planned with one hand (ikbirrt, unsimplified), followed with the other: "
        "how many collide, the d of the first row in contact, what the fingers touch there."
    )
    print(
        _common.markdown_table(
            [
                "robot",
                "problem",
                "`w`'s paths the law's hand collides on",
                "at d",
                "law's fingers → what",
                "law's paths `w` collides on",
                "at d",
                "`w`'s fingers → what",
            ],
            problem_rows(results),
            left=2,
        )
    )
    for robot in args.robots:
        mine = [r for r in results if r["problem"].robot.name == robot]
        totals = [sum(len(r["blocked"][h]) for r in mine) for h in ("w", "law")]
        runs = sum(r["seeds"] for r in mine)
        print(
            f"- {robot}: {totals[0]} of w's {runs} paths collide with the law's hand, "
            f"{totals[1]} of the law's {runs} with w"
        )
    print()
    print("Fingers in the palm frame at the home pose, ahead of the palm / span across [cm]:")
    laws = {r["problem"].robot.name: (r["problem"].robot, r["law"]) for r in results}
    print(
        _common.markdown_table(
            ["robot", "u", "`c`", "law's plateau (d = 1)", "law at `mga`", "`b`", "`w`"],
            extent_rows(list(laws.values())),
        )
    )
    print(f"figure written to {plot(results, args.out)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
