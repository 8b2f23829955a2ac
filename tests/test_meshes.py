"""Mesh shapes and movable obstacles in scene files (CONTRACT §3: ``shape = "mesh"``)."""

from __future__ import annotations

from pathlib import Path

import coal
import numpy as np
import pytest

import openup_ompl as ou
from openup_ompl.meshes import SHIPPED_MESHES, hull_points, write_shipped_meshes
from openup_ompl.physics.shapes import scene_spec
from openup_ompl.scene import Shape

MESHES = Path(__file__).resolve().parents[1] / "scenes" / "meshes"
BOTTLE_SCENE = Path(__file__).resolve().parents[1] / "scenes" / "panda_bottle.toml"
POSE = [0.6, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0]


def test_shipped_meshes_are_what_the_generator_writes(tmp_path):
    """The committed OBJ files are byte for byte what write_shipped_meshes generates."""
    written = write_shipped_meshes(tmp_path)
    assert sorted(p.stem for p in written) == sorted(SHIPPED_MESHES)
    for file in written:
        assert file.read_bytes() == (MESHES / file.name).read_bytes(), file.name


@pytest.mark.parametrize("name", sorted(SHIPPED_MESHES))
def test_shipped_meshes_have_solid_centred_hulls(name):
    """Each shipped mesh has a solid hull centred on its bounding box, a few cm across."""
    points = hull_points(MESHES / f"{name}.obj")
    low, high = points.min(axis=0), points.max(axis=0)
    np.testing.assert_allclose((low + high) / 2, 0.0, atol=1e-6)
    assert np.all(high - low > 0.03) and np.all(high - low < 0.25)


def test_scale_scales_the_hull():
    """A scale of 0.5 halves every hull coordinate."""
    full = hull_points(MESHES / "cup.obj")
    half = hull_points(MESHES / "cup.obj", 0.5)
    np.testing.assert_allclose(np.ptp(half, axis=0), np.ptp(full, axis=0) / 2, atol=1e-9)


def test_mesh_file_is_relative_to_the_scene_and_round_trips():
    """The shipped bottle scene reads its mesh beside it; to_table reads back equal."""
    problem = ou.load_scene(BOTTLE_SCENE)
    bottle = problem.object
    assert bottle is not None and bottle.shape == "mesh"
    assert bottle.file == (MESHES / "bottle.obj").resolve()
    again = Shape.from_table(bottle.to_table(), "again", is_object=True)
    assert again.to_table() == bottle.to_table()
    assert again.file == bottle.file and again.scale == bottle.scale == 1.0


def test_mesh_geometry_is_the_hull_and_padding_grows_it():
    """Coal sees the hull (distance from a point above the bottle's top) and padding
    moves every surface out by exactly the padding."""
    bottle = Shape("bottle", "mesh", np.array(POSE), file=MESHES / "bottle.obj", scale=1.0)
    probe = coal.Sphere(1e-6)
    at = coal.Transform3s(np.eye(3), np.array([0.0, 0.0, 0.15]))
    distances = []
    for padding in (0.0, 0.01):
        result = coal.DistanceResult()
        distances.append(
            coal.distance(
                bottle.geometry(padding), coal.Transform3s(), probe, at,
                coal.DistanceRequest(), result,
            )
        )  # fmt: skip
    assert distances[0] == pytest.approx(0.05, abs=1e-4)
    assert distances[1] == pytest.approx(0.04, abs=1e-4)


@pytest.mark.parametrize(
    ("text", "fault"),
    [
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n", "solid"),
        ("", "solid"),
    ],
)
def test_a_mesh_without_a_solid_hull_is_refused(tmp_path, text, fault):
    """A flat or empty mesh is a ConfigError naming the file, not a Coal crash."""
    file = tmp_path / "flat.obj"
    file.write_text(text)
    with pytest.raises(ou.ConfigError, match=fault) as error:
        Shape("flat", "mesh", np.array(POSE), file=file, scale=1.0)
    assert "flat.obj" in str(error.value)


@pytest.mark.parametrize(("name", "expected"), [("missing.obj", "existing"), ("x.ply", "end")])
def test_missing_or_unknown_mesh_files_are_refused(tmp_path, name, expected):
    """A missing file or an unknown suffix is refused, naming the path."""
    (tmp_path / "x.ply").write_text("ply\n")
    with pytest.raises(ou.ConfigError, match=expected):
        Shape("m", "mesh", np.array(POSE), file=tmp_path / name, scale=1.0)


def test_mesh_needs_its_file_and_only_its_keys():
    """A mesh without a file, or with a radius, is refused by the scene reader."""
    table = {"name": "m", "shape": "mesh", "pose": POSE}
    with pytest.raises(ou.ConfigError, match="file"):
        Shape.from_table(table, "scene: object", is_object=True, base=MESHES)
    with pytest.raises(ou.ConfigError, match="radius"):
        Shape.from_table({**table, "file": "cup.obj", "radius": 0.1}, "scene: object", base=MESHES)


def test_movable_obstacles_take_a_mass_and_fixed_ones_do_not():
    """movable = true allows a mass (default 0.1 kg); a fixed obstacle's mass is refused;
    the object cannot be marked movable."""
    table = {"name": "n", "shape": "sphere", "radius": 0.03, "pose": POSE}
    free = Shape.from_table({**table, "movable": True}, "o")
    assert free.movable and free.mass == pytest.approx(0.1)
    assert Shape.from_table(free.to_table(), "again").to_table() == free.to_table()
    with pytest.raises(ou.ConfigError, match="movable"):
        Shape.from_table({**table, "mass": 0.2}, "o")
    with pytest.raises(ou.ConfigError, match="object is free"):
        Shape.from_table({**table, "movable": True}, "o", is_object=True)
    with pytest.raises(ou.ConfigError, match="true or false"):
        Shape.from_table({**table, "movable": "yes"}, "o")


def test_the_depth_camera_and_physics_see_the_mesh():
    """The scene's MuJoCo spec holds the bottle as a mesh geom of its hull's size."""
    import mujoco

    problem = ou.load_scene(BOTTLE_SCENE)
    model = scene_spec(problem).compile()
    geom = model.geom("bottle")
    assert geom.type[0] == mujoco.mjtGeom.mjGEOM_MESH
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    # a ray straight down onto the bottle's axis stops at its top, 0.2 m above the table
    geomid = np.zeros(1, dtype=np.int32)
    distance = mujoco.mj_ray(
        model, data, np.array([0.6, 0.0, 0.5]), np.array([0.0, 0.0, -1.0]), None, 1, -1, geomid
    )
    assert distance == pytest.approx(0.3, abs=1e-3)
    assert model.geom(int(geomid[0])).name == "bottle"


@pytest.mark.slow
def test_a_mesh_object_is_planned_and_held_in_physics(tmp_path):
    """The bottle scene plans, its plan file reads back, and physics holds the bottle."""
    problem = ou.load_scene(BOTTLE_SCENE)
    plan = ou.GraspPlanningSetup(problem).solve(time_limit=10.0, seed=1)
    file = plan.save(tmp_path / "plan.json")
    from openup_ompl.physics import execute_plan

    record = execute_plan(file)
    assert record.success
