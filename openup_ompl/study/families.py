"""Scene families: every trial a distinct problem drawn from stated ranges.

A family is a robot and a kind of scene. Its instances are built in code from the robot's
shipped scene (``scenes/<robot>_can.toml``) as a template: the same start, table and
approach direction (the Panda from above, closing along the world y axis; the LWA3-SDH
from the side along +x, the thumb on -y), with the object placed within a few centimetres
of the template's and the whole set-up turned by a small yaw about the object's vertical.
Every range is a module constant, so the results page can quote it.

Kinds (:data:`KINDS`): ``can`` (isolated, the baseline), ``clutter`` (2-4 free
neighbours, the first one beside the closing direction), ``tall`` (a 0.2 m bottle of
0.1 kg), ``box`` (yaw matters), ``thin`` (the Panda: a plank on edge; the LWA3-SDH: a
stick), ``wall`` (a fixed board beside the object), ``shelf`` (boards on both sides and
behind) and ``mesh`` (a bottle of revolution written as an OBJ file).

Gaps (:data:`GAP_RANGE`) count from the farther of the object's surface and the
``u = 0`` hand: its fingers along the whole straight approach (the law's opening ``b``)
and closing from ``c`` to the closed configuration with nothing in the way; on the
LWA3-SDH's thumb side also the thumb pushed back to its joint limit, as the squeezed
object pushes it in physics (:meth:`~openup_ompl.study.geometry.HandSweep.reach`). So the
baseline ``u = 0`` never meets a neighbour when the pose is known, and opening wider
(``u > 0``) spends the gap. The Panda's boards and neighbours end level with the object's
top: its 0.2 m wide palm passes just above it. An instance whose fingers touch a neighbour
or board anywhere on the ``u = 0`` approach, or whose neighbours overlap, is redrawn
(:func:`instance_problem`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from openup_ompl._resources import data_dir
from openup_ompl.exceptions import ConfigError
from openup_ompl.meshes import revolution_mesh, write_obj
from openup_ompl.robot import Robot
from openup_ompl.scene import Problem, Shape, load_scene
from openup_ompl.study.geometry import SUPPORT, HandSweep, shape_distance

__all__ = [
    "KINDS",
    "MOVABLE_NEIGHBOURS",
    "ROBOTS",
    "Family",
    "instance_problem",
    "parse_families",
]

#: The robots with families, and the shipped scene each one's template is.
ROBOTS = {"panda": "panda_can.toml", "lwa3_sdh": "lwa3_sdh_can.toml"}
KINDS = ("can", "clutter", "tall", "box", "thin", "wall", "shelf", "mesh")

#: Object centre's horizontal offset from the template's [m], each axis uniform in +-.
PLACE_RANGE = (0.03, 0.04)
#: The set-up's yaw about the object's vertical [rad], uniform in +-.
YAW_RANGE = 0.25
#: Gap [m] between the object's surface and a neighbour's or wall's.
GAP_RANGE = (0.005, 0.04)
#: Neighbours per clutter instance (inclusive).
NEIGHBOURS = (2, 4)
#: Draws of one instance before giving up (the u = 0 approach must be clear).
MAX_DRAWS = 60
#: The Panda's fingertips reach this far below the object's top [m] (the template's).
PANDA_PALM_ABOVE_TOP = 0.07
#: Clearance [m] of each Panda finger to the object in its closed preshape ``c``.
PANDA_PRESHAPE_GAP = 0.005


def _movable_supported() -> bool:
    return "movable" in {f.name for f in dataclasses.fields(Shape)}


#: Neighbours and walls are free bodies in physics when the scene supports movable
#: obstacles; until then they are fixed (the one switch).
MOVABLE_NEIGHBOURS = _movable_supported()


@dataclass(frozen=True)
class _Frame:
    """An instance's local frame: origin on the table under the object's centre, x along
    the robot's approach (horizontal), y along the closing direction, z up."""

    origin: np.ndarray
    yaw: float

    def pose(self, x: float, y: float, z: float, yaw: float = 0.0) -> np.ndarray:
        """World ``[x, y, z, qx, qy, qz, qw]`` of a local position and yaw."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        world = self.origin + np.array([c * x - s * y, s * x + c * y, z])
        q = pin.Quaternion(pin.utils.rpyToMatrix(0.0, 0.0, self.yaw + yaw))
        return np.array([*world, q.x, q.y, q.z, q.w])

    def grasp(self, template: np.ndarray, x: float, y: float, z: float) -> np.ndarray:
        """The template's grasp rotation turned by the frame's yaw, at a local position."""
        turn = pin.utils.rpyToMatrix(0.0, 0.0, self.yaw)
        rotation = turn @ pin.XYZQUATToSE3(template).rotation
        q = pin.Quaternion(rotation)
        return np.array([*self.pose(x, y, z)[:3], q.x, q.y, q.z, q.w])


@dataclass(frozen=True)
class Family:
    """A robot and a kind of scene, or a user's scene file (``scene``: only the pose
    error is drawn for it).

    Attributes:
        name: ``"<robot>-<kind>"``, or the scene file's stem.
        robot: Robot name (a shipped robot, or the scene's).
        kind: One of :data:`KINDS`, or ``"scene"``.
        scene: The user's scene file (``kind == "scene"`` only).
    """

    name: str
    robot: str
    kind: str
    scene: Path | None = None

    def to_json(self) -> dict[str, Any]:
        """The family as JSON-ready values.

        Returns:
            ``{"name", "robot", "kind", "scene"}`` (``scene`` a path string or ``None``).
        """
        return {"name": self.name, "robot": self.robot, "kind": self.kind,
                "scene": None if self.scene is None else str(self.scene)}  # fmt: skip

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> Family:
        """The family of :meth:`to_json`'s values.

        Args:
            data: ``{"name", "robot", "kind", "scene"}``.

        Returns:
            The family.
        """
        scene = data.get("scene")
        return cls(data["name"], data["robot"], data["kind"], Path(scene) if scene else None)


def parse_families(names: list[str] | None, scene: str | Path | None = None) -> list[Family]:
    """Families from names: ``"<robot>-<kind>"``, a bare kind (for every robot of
    :data:`ROBOTS`), ``"all"``; and a user's scene file.

    Args:
        names: Family names, or ``None``.
        scene: A user's scene file, its own family, or ``None``.

    Returns:
        The families, the scene's first.

    Raises:
        ConfigError: An unknown robot or kind, or nothing asked for.
    """
    families: list[Family] = []
    if scene is not None:
        path = Path(scene).expanduser().resolve()
        problem = load_scene(path)
        families.append(Family(path.stem, problem.robot.spec.name, "scene", path))
    for name in names or ([] if scene is not None else ["all"]):
        robot, _, kind = name.rpartition("-")
        robots = [robot] if robot else list(ROBOTS)
        kinds = list(KINDS) if kind == "all" else [kind]
        if robot and robot not in ROBOTS:
            raise ConfigError("family", name, f"'<robot>-<kind>' with a robot of {list(ROBOTS)}")
        if any(k not in KINDS for k in kinds):
            raise ConfigError("family", name, f"a kind of {list(KINDS)} or 'all'")
        for r in robots:
            for k in kinds:
                families.append(Family(f"{r}-{k}", r, k))
    if not families:
        raise ConfigError("family", names, "at least one family or a --scene")
    return families


def _cylinder(name: str, frame: _Frame, r: float, h: float, x: float = 0.0, y: float = 0.0,
              **physics: Any) -> Shape:  # fmt: skip
    return Shape(name, "cylinder", frame.pose(x, y, h / 2), radius=r, length=h, **physics)


def _box(name: str, frame: _Frame, size: tuple[float, float, float], x: float = 0.0,
         y: float = 0.0, z: float | None = None, **physics: Any) -> Shape:  # fmt: skip
    z = size[2] / 2 if z is None else z
    return Shape(name, "box", frame.pose(x, y, z), size=np.asarray(size), **physics)


@dataclass
class _Draw:
    """One instance being drawn: its frame, generator and robot."""

    robot: str
    frame: _Frame
    rng: np.random.Generator
    mesh_dir: Path | None

    def uniform(self, low: float, high: float) -> float:
        return float(self.rng.uniform(low, high))

    def radius(self) -> float:
        return self.uniform(0.026, 0.031) if self.robot == "panda" else self.uniform(0.029, 0.036)

    def neighbour(self, name: str, obj_r: float, obj_h: float, angle: float) -> Shape:
        r, gap = self.uniform(0.02, 0.035), self.uniform(*GAP_RANGE)
        # The Panda's palm, 0.2 m wide along the closing axis, passes just above the
        # object's top: a neighbour no taller than the object stays under it.
        h = obj_h * self.uniform(0.6, 1.0 if self.robot == "panda" else 1.1)
        distance = obj_r + gap + r
        x, y = distance * math.cos(angle), distance * math.sin(angle)
        physics = {"movable": True, "mass": self.uniform(0.1, 0.3)} if MOVABLE_NEIGHBOURS else {}
        return _cylinder(name, self.frame, r, h, x, y, **physics)

    def wall(self, name: str, side: float, half: float, height: float) -> Shape:
        """A fixed board along the approach, ``side`` +1 / -1 of the closing axis."""
        y = side * (half + self.uniform(*GAP_RANGE) + 0.01)
        return _box(name, self.frame, (0.3, 0.02, height), 0.05, y)


def _object(kind: str, draw: _Draw) -> tuple[Shape, float, float]:
    """The object, its half-width along the closing axis and its height [m]."""
    f, u = draw.frame, draw.uniform
    if kind == "tall":
        r = draw.radius() - (0.002 if draw.robot == "panda" else 0.0)
        return _cylinder("bottle", f, r, 0.2, mass=0.1), r, 0.2
    if kind == "box":
        size = (u(0.05, 0.07), u(0.045, 0.06), u(0.10, 0.16))
        return _box("box", f, size, mass=u(0.1, 0.25)), size[1] / 2, size[2]
    if kind == "thin" and draw.robot == "panda":
        size = (u(0.10, 0.14), u(0.015, 0.025), u(0.10, 0.14))
        return _box("plank", f, size, mass=u(0.08, 0.15)), size[1] / 2, size[2]
    if kind == "thin":
        r, h = u(0.012, 0.018), u(0.18, 0.22)
        return _cylinder("stick", f, r, h, mass=u(0.05, 0.1)), r, h
    if kind == "mesh":
        return _mesh_object(draw)
    h = u(0.10, 0.14) if draw.robot == "panda" else u(0.14, 0.18)
    r = draw.radius()
    return _cylinder("can", f, r, h, mass=u(0.1, 0.3)), r, h


def _mesh_object(draw: _Draw) -> tuple[Shape, float, float]:
    """A bottle (body, shoulder, neck) drawn as a profile of revolution, written as an OBJ
    file (:func:`~openup_ompl.meshes.revolution_mesh`) centred on its middle."""
    if draw.mesh_dir is None:
        raise ConfigError("mesh_dir", None, "a directory for the mesh family's OBJ files")
    r, h = draw.radius(), draw.uniform(0.14, 0.18)
    shoulder, neck = r * draw.uniform(0.8, 1.0), r * draw.uniform(0.4, 0.5)
    profile = np.array(
        [[0.0, 0.0], [0.9 * r, 0.0], [r, 0.1 * h], [r, 0.55 * h], [shoulder, 0.7 * h],
         [neck, 0.85 * h], [neck, h], [0.0, h]]
    )  # fmt: skip
    vertices, triangles = revolution_mesh(profile)
    vertices = vertices - np.array([0.0, 0.0, h / 2])
    draw.mesh_dir.mkdir(parents=True, exist_ok=True)
    name = f"bottle_{int(draw.rng.integers(1 << 30)):09d}.obj"
    path = write_obj(draw.mesh_dir / name, vertices, triangles, "openup-ompl study: a bottle")
    shape = Shape("bottle", "mesh", draw.frame.pose(0, 0, h / 2), file=path, scale=1.0, mass=0.15)
    return shape, r, h


def _side(reach: np.ndarray, sign: float) -> float:
    """The reach [m] on the ``+y`` (``sign >= 0``) or ``-y`` side."""
    return float(reach[1] if sign >= 0 else reach[2])


def _obstacles(kind: str, draw: _Draw, reach: np.ndarray, height: float) -> list[Shape]:
    """The neighbours or walls of a kind (none for an isolated object); ``reach``: how
    far the object or the ``u = 0`` hand extends from the object's axis along local +x,
    +y and -y [m] (gaps are measured from there)."""
    sign = 1.0 if draw.rng.random() < 0.5 else -1.0
    # Boards stand 5 cm above the object beside the LWA3-SDH's side approach; the Panda's
    # palm passes just above the object's top, so its boards end level with it.
    board = height + (0.0 if draw.robot == "panda" else 0.05)
    if kind == "wall":
        return [draw.wall("wall", sign, _side(reach, sign), board)]
    if kind == "shelf":
        x = reach[0] + draw.uniform(*GAP_RANGE) + 0.01
        back = _box("back", draw.frame, (0.02, 0.4, board), x)
        sides = [draw.wall(f"side_{i}", s, _side(reach, s), board) for i, s in enumerate((1, -1))]
        return [*sides, back]
    if kind != "clutter":
        return []
    count = int(draw.rng.integers(NEIGHBOURS[0], NEIGHBOURS[1] + 1))
    # The first beside the closing direction (where an opening hand meets it), the rest
    # anywhere off the approach corridor (the LWA3-SDH comes from local -x).
    limit = math.pi if draw.robot == "panda" else math.radians(120)
    first = sign * math.pi / 2 + draw.uniform(-0.4, 0.4)
    neighbours = [draw.neighbour("neighbour_0", _side(reach, sign), height, first)]
    for i in range(1, count):
        angle = draw.uniform(-limit, limit)
        side = _side(reach, math.sin(angle))
        offset = float(np.hypot(reach[0] * math.cos(angle), side * math.sin(angle)))
        neighbours.append(draw.neighbour(f"neighbour_{i}", offset, height, angle))
    return neighbours


def _overlaps(obstacles: list[Shape], obj: Shape) -> bool:
    """The object and a neighbour, or two neighbours, closer than 2 mm (walls and
    shelf boards may meet each other: they are one fixed piece)."""
    if obj.shape == "mesh":
        return False
    others = [s for s in obstacles if s.name != SUPPORT]
    free = [s for s in others if s.name.startswith("neighbour")]
    pairs = [(obj, s) for s in others] + [(a, b) for i, a in enumerate(free) for b in free[i + 1 :]]
    return any(shape_distance(a, b) < 0.002 for a, b in pairs)


def _hand(robot: Robot, template: Problem, half: float) -> Any:
    """The law for this object: the Panda's preshape ``c`` fits its width (the template's
    5 mm a side); the LWA3-SDH's is the robot's own wrap."""
    law = template.hand_law
    if robot.spec.name != "panda":
        return law
    c = np.full_like(law.c, min(half + PANDA_PRESHAPE_GAP, law.w[0] - 0.002))
    return law.with_options(c=c, b=np.minimum(c + 0.002, law.w))


def _grasp(robot: str, frame: _Frame, template: Problem, height: float) -> np.ndarray:
    if robot == "panda":
        return frame.grasp(template.grasp_pose, 0.0, 0.0, height + PANDA_PALM_ABOVE_TOP)
    # The LWA3-SDH's template: palm 0.10 m back from the axis, 9.5 mm towards the thumb,
    # 0.10 m above the table.
    assert template.object is not None
    offset = template.grasp_pose[:3] - template.object.pose[:3]
    return frame.grasp(template.grasp_pose, offset[0], offset[1], template.grasp_pose[2])


def _draw_once(family: Family, template: Problem, draw: _Draw) -> Problem:
    obj, half, height = _object(family.kind, draw)
    support = [s for s in template.obstacles if s.name == SUPPORT]
    grasp = _grasp(family.robot, draw.frame, template, height)
    law = _hand(template.robot, template, half)
    bare = Problem(template.robot, template.start, grasp, law, support, obj)
    turn = draw.frame.yaw
    x = np.array([math.cos(turn), math.sin(turn), 0.0])
    y = np.array([-math.sin(turn), math.cos(turn), 0.0])
    # Gaps count from the farther of the object's surface and the u = 0 hand (its whole
    # approach and its closing): the baseline is clear of every neighbour by construction.
    # The LWA3-SDH's thumb (local -y) yields to its limit when the fingers push the object
    # against it: on that side gaps count from the thumb opened to w.
    sweep = HandSweep(bare)
    ahead, left = sweep.reach(obj.pose[:3], [x, y])
    (right,) = sweep.reach(obj.pose[:3], [-y], yielded=family.robot == "lwa3_sdh")
    reach = np.array([max(half, ahead), max(half, left), max(half, right)])
    obstacles = support + _obstacles(family.kind, draw, reach, height)
    return dataclasses.replace(bare, obstacles=obstacles)


def instance_problem(
    family: Family,
    rng: np.random.Generator,
    template: Problem,
    mesh_dir: Path | None = None,
) -> Problem:
    """Draw one instance of ``family`` (``template``: its robot's shipped scene, loaded;
    or for a ``"scene"`` family the user's scene, returned as it is).

    Args:
        family: The family.
        rng: The instance's generator (placement, yaw and obstacles drawn from it).
        template: The family's template scene (:func:`template_scene`).
        mesh_dir: Directory the mesh family's OBJ files are written to (needed for it).

    Returns:
        The instance's problem, its object clear of the obstacles and its approach clear
        at ``u = 0``.

    Raises:
        ConfigError: No clear instance in :data:`MAX_DRAWS` draws.
    """
    if family.kind == "scene":
        return template
    assert template.object is not None
    centre = template.object.pose[:3].copy()
    for _ in range(MAX_DRAWS):
        offset = [rng.uniform(-r, r) for r in PLACE_RANGE]
        origin = np.array([centre[0] + offset[0], centre[1] + offset[1], 0.0])
        frame = _Frame(origin, float(rng.uniform(-YAW_RANGE, YAW_RANGE)))
        problem = _draw_once(family, template, _Draw(family.robot, frame, rng, mesh_dir))
        assert problem.object is not None
        if _overlaps(problem.obstacles, problem.object):
            continue
        if HandSweep(problem).approach_clear():
            return problem
    raise ConfigError("family", family.name, f"an instance clear at u = 0 in {MAX_DRAWS} draws")


def template_scene(family: Family, robot: Robot | None = None) -> Problem:
    """The scene a family's instances are drawn from (its robot's shipped scene).

    Args:
        family: The family.
        robot: Its robot already loaded (``None``: loaded here).

    Returns:
        The scene, loaded.

    Raises:
        ConfigError, RobotNotFound: What :func:`~openup_ompl.scene.load_scene` raises.
    """
    if family.scene is not None:
        return load_scene(family.scene, robot)
    return load_scene(data_dir("scenes") / ROBOTS[family.robot], robot)
