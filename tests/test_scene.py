"""Scene files (CONTRACT §3): robot, start, grasp, hand-law overrides, object, obstacles."""

from __future__ import annotations

import coal
import numpy as np
import pytest

import openup_ompl as ou

CAN_START = "start = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785]"
CAN_GRASP = "pose = [0.6, 0.0, 0.19, 1.0, 0.0, 0.0, 0.0]"


def edited(text: str, old: str, new: str) -> str:
    """``text`` with its single occurrence of ``old`` replaced (fails loudly if absent)."""
    assert text.count(old) == 1, f"{old!r} is not exactly once in the scene"
    return text.replace(old, new)


def test_default_scene_loads(panda):
    """The default scene loads its start, grasp, object and obstacles as written."""
    problem = ou.load_scene(ou.default_scene_path(), robot=panda)
    assert problem.robot is panda
    assert problem.path == ou.default_scene_path().resolve()
    np.testing.assert_allclose(problem.start, [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
    np.testing.assert_allclose(problem.grasp_pose, [0.6, 0.0, 0.19, 1.0, 0.0, 0.0, 0.0])
    assert [s.name for s in problem.obstacles] == ["table", "wall"]
    assert all(s.shape == "box" for s in problem.obstacles)
    np.testing.assert_allclose(problem.obstacles[1].size, [0.04, 0.4, 0.22])
    assert problem.object is not None
    assert (problem.object.name, problem.object.shape) == ("can", "cylinder")
    assert (problem.object.radius, problem.object.length) == (0.03, 0.12)
    assert [s.name for s in problem.environment] == ["table", "wall", "can"]


def test_default_scene_loads_its_own_robot():
    """Without robot=, load_scene loads the robot the scene names."""
    problem = ou.load_scene(ou.default_scene_path())
    assert problem.robot.name == "panda"
    assert problem.robot.spec.path == ou.available_robots()["panda"].resolve()


def test_default_scene_applies_hand_law_overrides(panda):
    """The scene's [hand] overrides c, b, u and mga; w stays the robot's."""
    law = ou.load_scene(ou.default_scene_path(), robot=panda).hand_law
    np.testing.assert_allclose(law.c, [0.035, 0.035])
    assert law.u == 0.3
    assert law.mga == 0.25
    np.testing.assert_allclose(law.b, [0.037, 0.037])
    np.testing.assert_allclose(law.w, panda.spec.w)
    np.testing.assert_allclose(law.lower, [0.0, 0.0])
    np.testing.assert_allclose(law.upper, [0.04, 0.04])


def test_scene_selects_the_open_arrival_variant(panda, default_scene_text, write_file):
    """[hand] open_arrival = true gives the law that reaches the grasp at c + (w - c) u."""
    path = write_file(
        "open.toml", edited(default_scene_text, "u = 0.3", "u = 0.3\nopen_arrival = true")
    )
    law = ou.load_scene(path, robot=panda).hand_law
    assert law.open_arrival
    np.testing.assert_allclose(law(0.0), law.c + (law.w - law.c) * 0.3)


def test_scene_without_hand_table_uses_robot_law(panda, empty_scene_text, write_file):
    """A scene with no [hand] and no start gets the robot's law and the robot's home."""
    problem = ou.load_scene(write_file("plain.toml", empty_scene_text), robot=panda)
    np.testing.assert_allclose(problem.hand_law.c, panda.spec.c)
    assert problem.hand_law.u == panda.spec.u
    np.testing.assert_allclose(problem.start, panda.spec.home)
    assert problem.obstacles == [] and problem.object is None


@pytest.mark.parametrize(
    "quaternion", ["0.0, 0.0, 0.0, 1.0005", "1.0005, 0.0, 0.0, 0.0", "0.7072, 0.7072, 0.0, 0.0"]
)
def test_grasp_pose_is_normalised(panda, default_scene_text, write_file, quaternion):
    """A nearly unit grasp quaternion (within 1e-3) is normalised to unit length."""
    text = edited(default_scene_text, CAN_GRASP, f"pose = [0.6, 0.0, 0.19, {quaternion}]")
    problem = ou.load_scene(write_file("scene.toml", text), robot=panda)
    assert np.linalg.norm(problem.grasp_pose[3:]) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(problem.grasp_pose[:3], [0.6, 0.0, 0.19])


SHAPES = {
    "box": 'shape = "box"\nsize = [0.1, 0.2, 0.3]',
    "cylinder": 'shape = "cylinder"\nradius = 0.05\nlength = 0.2',
    "sphere": 'shape = "sphere"\nradius = 0.07',
}


def check_shape(shape: ou.Shape, kind: str, name: str, pose: list[float]) -> None:
    """Assert a loaded shape's kind, name, pose and Coal geometry match SHAPES[kind]."""
    assert (shape.name, shape.shape) == (name, kind)
    np.testing.assert_allclose(shape.pose, pose)
    np.testing.assert_allclose(shape.placement.translation, pose[:3])
    geometry = shape.geometry()
    if kind == "box":
        assert isinstance(geometry, coal.Box)
        np.testing.assert_allclose(geometry.halfSide, [0.05, 0.1, 0.15])
    elif kind == "cylinder":
        assert isinstance(geometry, coal.Cylinder)
        assert (geometry.radius, geometry.halfLength) == pytest.approx((0.05, 0.1))
    else:
        assert isinstance(geometry, coal.Sphere)
        assert geometry.radius == pytest.approx(0.07)


def test_every_shape_loads_as_obstacle(panda, empty_scene_text, write_file):
    """Boxes, cylinders and spheres all load as obstacles, in file order."""
    text = empty_scene_text
    for i, (kind, body) in enumerate(SHAPES.items()):
        text += f'\n[[obstacles]]\nname = "o_{kind}"\n{body}\n'
        text += f"pose = [1.0, {i}.0, 0.5, 0.0, 0.0, 0.0, 1.0]\n"
    problem = ou.load_scene(write_file("shapes.toml", text), robot=panda)
    assert len(problem.obstacles) == 3
    for i, (kind, shape) in enumerate(zip(SHAPES, problem.obstacles, strict=True)):
        check_shape(shape, kind, f"o_{kind}", [1.0, float(i), 0.5, 0.0, 0.0, 0.0, 1.0])


@pytest.mark.parametrize("kind", sorted(SHAPES))
def test_every_shape_loads_as_object(panda, empty_scene_text, write_file, kind):
    """Boxes, cylinders and spheres all load as the object to grasp."""
    text = empty_scene_text + f'\n[object]\nname = "thing"\n{SHAPES[kind]}\n'
    text += "pose = [0.6, 0.1, 0.05, 0.0, 0.0, 0.0, 1.0]\n"
    problem = ou.load_scene(write_file("object.toml", text), robot=panda)
    assert problem.object is not None
    check_shape(problem.object, kind, "thing", [0.6, 0.1, 0.05, 0.0, 0.0, 0.0, 1.0])
    assert problem.environment == [problem.object]


# (old, new, key the error must name): each edit of the default scene makes it invalid.
BAD_EDITS = {
    "nan in pose": (CAN_GRASP, "pose = [0.6, nan, 0.19, 1.0, 0.0, 0.0, 0.0]", "grasp.pose"),
    "pose of 6": (CAN_GRASP, "pose = [0.6, 0.0, 0.19, 1.0, 0.0, 0.0]", "grasp.pose"),
    "non-unit quaternion": (CAN_GRASP, "pose = [0.6, 0.0, 0.19, 1.0, 1.0, 0.0, 0.0]", "grasp.pose"),
    "nan in object pose": (
        "pose = [0.6, 0.0, 0.06, 0.0, 0.0, 0.0, 1.0]",
        "pose = [0.6, 0.0, 0.06, 0.0, 0.0, 0.0, nan]",
        "object.pose",
    ),
    "unknown shape": ('shape = "cylinder"', 'shape = "cone"', "object.shape"),
    "negative size": ("size = [0.04, 0.4, 0.22]", "size = [0.04, -0.4, 0.22]", "obstacles[1].size"),
    "negative radius": ("radius = 0.03", "radius = -0.03", "object.radius"),
    # Past MAX_EXTENT Coal's mesh checks lose their precision (1e12 m touches every link).
    "box beyond a kilometre": (
        "size = [0.04, 0.4, 0.22]",
        "size = [0.04, 1e300, 0.22]",
        "obstacles[1].size",
    ),
    "radius beyond a kilometre": ("radius = 0.03", "radius = 1e12", "object.radius"),
    "object beyond a kilometre": (
        "pose = [0.6, 0.0, 0.06, 0.0, 0.0, 0.0, 1.0]",
        "pose = [0.6, 2e3, 0.06, 0.0, 0.0, 0.0, 1.0]",
        "object.pose",
    ),
    "missing grasp": ("[grasp]", "[grab]", "grasp"),
    "missing robot": ('robot = "panda"', "", "bad_scene.toml: robot"),
    "u above 1": ("u = 0.3", "u = 1.5", "hand.u"),
    "u below 0": ("u = 0.3", "u = -0.1", "hand.u"),
    "mga zero": ("mga = 0.25", "mga = 0.0", "hand.mga"),
    "mga too small": ("mga = 0.25", "mga = 1e-9", "hand.mga"),  # would not end: MGA_MIN
    "unknown hand key": ("u = 0.3", "u = 0.3\nspread = 1.0", "hand.spread"),
    "open_arrival not a bool": ("u = 0.3", 'u = 0.3\nopen_arrival = "yes"', "hand.open_arrival"),
    "c of wrong length": ("c = [0.035, 0.035]", "c = [0.035]", "hand.c"),
    "c of strings": ("c = [0.035, 0.035]", 'c = ["a", "b"]', "hand.c"),
    "start nested 5000 deep": (CAN_START, "start = " + "[" * 5000 + "]" * 5000, "scene"),
    "typo at the top level": (CAN_START, CAN_START.replace("start", "strat"), "strat"),
    "typo in the object": ("radius = 0.03", "raduis = 0.03", "object.raduis"),
    "a box with a radius": (
        "size = [0.04, 0.4, 0.22]",
        "size = [0.04, 0.4, 0.22]\nradius = 1",
        "obstacles[1].radius",
    ),
    "typo in the grasp": ("[grasp]\n", "[grasp]\nposition = 1\n", "grasp.position"),
    "duplicate obstacles": ('name = "wall"', 'name = "table"', "table"),
    "object named like an obstacle": ('name = "can"', 'name = "wall"', "wall"),
    "start of 6": (CAN_START, "start = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571]", "start"),
    "start outside limits": (
        CAN_START,
        "start = [0.0, -0.785, 0.0, 0.5, 0.0, 1.571, 0.785]",
        "start: joint panda_joint4",
    ),
}


@pytest.mark.parametrize(("old", "new", "key"), BAD_EDITS.values(), ids=BAD_EDITS.keys())
def test_bad_scene_raises_config_error_naming_file_and_key(
    panda, default_scene_text, write_file, old, new, key
):
    """An invalid value raises ConfigError whose message names the scene file and the key."""
    path = write_file("bad_scene.toml", edited(default_scene_text, old, new))
    with pytest.raises(ou.ConfigError) as info:
        ou.load_scene(path, robot=panda)
    message = str(info.value)
    assert "bad_scene.toml" in message
    assert key in message


def test_bad_hand_distance_names_file_and_key(panda, default_scene_text, write_file):
    """An unknown hand.distance raises ConfigError naming the scene file and hand.distance."""
    text = edited(default_scene_text, "u = 0.3", 'u = 0.3\ndistance = "manhattan"')
    with pytest.raises(ou.ConfigError) as info:
        ou.load_scene(write_file("bad_scene.toml", text), robot=panda)
    assert "bad_scene.toml" in str(info.value)
    assert "hand.distance" in str(info.value)


def test_malformed_toml_raises_config_error_naming_the_file(panda, default_scene_text, write_file):
    """A TOML syntax error raises ConfigError naming the file and the error's position."""
    path = write_file("broken.toml", edited(default_scene_text, "u = 0.3", "u = "))
    with pytest.raises(ou.ConfigError) as info:
        ou.load_scene(path, robot=panda)
    assert str(path) in str(info.value)
    assert "line" in str(info.value)


def test_missing_scene_file_raises_config_error(tmp_path):
    """A scene path that does not exist raises ConfigError naming it."""
    path = tmp_path / "absent.toml"
    with pytest.raises(ou.ConfigError, match="absent.toml"):
        ou.load_scene(path)


def test_unknown_robot_in_scene_raises_robot_not_found(default_scene_text, write_file):
    """A scene naming an unknown robot raises RobotNotFound."""
    text = edited(default_scene_text, 'robot = "panda"', 'robot = "r2d2"')
    with pytest.raises(ou.RobotNotFound, match="r2d2"):
        ou.load_scene(write_file("scene.toml", text))


def test_scene_robot_may_be_a_relative_path(panda_toml, default_scene_text, tmp_path):
    """A scene's robot may be a robot TOML path relative to the scene file."""
    (tmp_path / "robots").mkdir()
    (tmp_path / "robots" / "mypanda.toml").write_text(panda_toml)
    scene = tmp_path / "scene.toml"
    scene.write_text(edited(default_scene_text, 'robot = "panda"', 'robot = "robots/mypanda.toml"'))
    problem = ou.load_scene(scene)
    assert problem.robot.spec.path == (tmp_path / "robots" / "mypanda.toml").resolve()


def test_object_physics_keys_default_and_validate(tmp_path):
    """[object] mass and friction default to 0.1 kg and 0.6; bad values name the key."""
    import openup_ompl as oo
    from openup_ompl.scene import OBJECT_FRICTION, OBJECT_MASS

    problem = oo.load_scene(oo.default_scene_path())
    assert problem.object is not None
    assert (problem.object.mass, problem.object.friction) == (OBJECT_MASS, OBJECT_FRICTION)
    text = oo.default_scene_path().read_text()
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace('name = "can"', 'name = "can"\nmass = -1.0'))
    with pytest.raises(oo.ConfigError, match="object.mass"):
        oo.load_scene(bad)


def test_unknown_key_names_the_nearest_valid_one(panda, default_scene_text, write_file):
    """A typo in a scene key is refused, naming the key and the valid key it is nearest."""
    path = write_file(
        "typo.toml", edited(default_scene_text, CAN_START, CAN_START.replace("start", "strat"))
    )
    with pytest.raises(ou.ConfigError, match="did you mean 'start'"):
        ou.load_scene(path, robot=panda)
