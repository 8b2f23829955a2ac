"""Bad robot input (robot files, their URDFs and meshes) refused at loading with a
:class:`~openup_ompl.exceptions.ConfigError` naming the file and the value at fault."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import openup_ompl as ou

#: A two-joint arm (a1, a2), a palm and a one-finger hand; ``{...}`` are filled by
#: :func:`write_robot`. ``extra`` hangs from the palm, in neither joint list.
URDF = """<robot name="toy">
  <link name="base_link"/>
  <joint name="a1" type="revolute">
    <parent link="base_link"/><child link="link1"/><axis xyz="0 0 1"/>
    <limit lower="{a1_lower}" upper="{a1_upper}" effort="1" velocity="1"/>
  </joint>
  <link name="link1">
    <collision><origin xyz="0 0 0.1"/><geometry>{link1}</geometry></collision>
  </link>
  <joint name="a2" type="revolute">
    <parent link="link1"/><child link="link2"/><origin xyz="0 0 0.2"/><axis xyz="0 1 0"/>
    <limit lower="-2" upper="2" effort="1" velocity="1"/>
  </joint>
  <link name="link2">
    <collision><origin xyz="0 0 0.1"/><geometry>{link2}</geometry></collision>
  </link>
  <joint name="palm_joint" type="fixed">
    <parent link="link2"/><child link="palm"/><origin xyz="0 0 0.25"/>
  </joint>
  <link name="palm">
    <collision><geometry><box size="0.08 0.08 0.02"/></geometry></collision>
  </link>
  <joint name="finger" type="prismatic">
    <parent link="palm"/><child link="finger_link"/><origin xyz="0.02 0 0.03"/>
    <axis xyz="1 0 0"/><limit lower="0" upper="0.04" effort="1" velocity="1"/>
  </joint>
  <link name="finger_link">
    <collision><geometry><box size="0.01 0.02 0.04"/></geometry></collision>
  </link>
  <joint name="extra" type="revolute">
    <parent link="palm"/><child link="extra_link"/><origin xyz="-0.03 0 0.03"/>
    <axis xyz="0 1 0"/><limit lower="{extra_lower}" upper="{extra_upper}" effort="1" velocity="1"/>
  </joint>
  <link name="extra_link"/>
</robot>
"""

ROBOT = """name = "toy"
urdf = "toy.urdf"
palm_frame = "{palm_frame}"
arm_joints = ["a1", "a2"]
hand_joints = ["finger"]
home = [0.0, 0.3]
convex = {convex}
[hand]
c = {c}
b = [0.02]
w = [0.03]
mga = 0.25
"""

CYLINDER = '<cylinder radius="0.03" length="0.2"/>'


def write_robot(
    directory: Path,
    *,
    link1: str = CYLINDER,
    link2: str = CYLINDER,
    a1_limits: tuple[float, float] = (-2.0, 2.0),
    extra_limits: tuple[float, float] = (-1.0, 1.0),
    palm_frame: str = "palm",
    convex: bool = True,
    c: str = "[0.01]",
    tail: str = "",
) -> Path:
    """Write ``toy.urdf`` and its robot file ``toy.toml`` (plus ``tail``) to ``directory``."""
    urdf = URDF.format(
        link1=link1,
        link2=link2,
        a1_lower=a1_limits[0],
        a1_upper=a1_limits[1],
        extra_lower=extra_limits[0],
        extra_upper=extra_limits[1],
    )
    (directory / "toy.urdf").write_text(urdf)
    text = ROBOT.format(palm_frame=palm_frame, convex=str(convex).lower(), c=c) + tail
    path = directory / "toy.toml"
    path.write_text(text)
    return path


def write_stl(path: Path, triangles: np.ndarray) -> Path:
    """An ASCII STL of ``triangles`` (shape ``(n, 3, 3)``, vertices [m])."""
    lines = ["solid mesh"]
    for triangle in np.asarray(triangles, dtype=float):
        lines += ["facet normal 0 0 0", "outer loop"]
        lines += [f"vertex {x:.9g} {y:.9g} {z:.9g}" for x, y, z in triangle]
        lines += ["endloop", "endfacet"]
    path.write_text("\n".join([*lines, "endsolid mesh", ""]))
    return path


#: A flat square: two triangles in the plane z = 0.
SQUARE = [[[0, 0, 0], [0.1, 0, 0], [0.1, 0.1, 0]], [[0, 0, 0], [0.1, 0.1, 0], [0, 0.1, 0]]]


def test_robot_of_this_file_loads(tmp_path):
    """The toy robot the other tests spoil loads as written (their errors are not its)."""
    robot = ou.load_robot(write_robot(tmp_path))
    assert robot.spec.arm_joints == ("a1", "a2")


@pytest.mark.slow
def test_flat_mesh_with_convex_hulls_exits_with_one_error_line(tmp_path):
    """A mesh whose vertices lie in one plane (Coal's hull crashed the process) is one
    error line, exit 2, naming the mesh, its link and the convex key."""
    mesh = write_stl(tmp_path / "flat.stl", SQUARE)
    write_robot(tmp_path, link2=f'<mesh filename="{mesh}"/>')
    scene = tmp_path / "scene.toml"
    scene.write_text('robot = "toy.toml"\n[grasp]\npose = [0.3, 0.0, 0.3, 0.0, 0.0, 0.0, 1.0]\n')
    result = subprocess.run(
        [sys.executable, "-m", "openup_ompl", "plan", str(scene), "--time", "1"],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=tmp_path,
    )
    assert result.returncode == 2, result.stderr
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("openup-ompl: error: "), result.stderr
    for named in ("toy.toml", "link link2", str(mesh), "convex = false"):
        assert named in lines[0]


def test_flat_mesh_loads_without_convex_hulls(tmp_path):
    """The remedy the flat-mesh error gives, convex = false, loads that robot."""
    mesh = write_stl(tmp_path / "flat.stl", SQUARE)
    robot = ou.load_robot(write_robot(tmp_path, link2=f'<mesh filename="{mesh}"/>', convex=False))
    assert any(str(mesh) == g.meshPath for g in robot.collision_model.geometryObjects)


def test_mesh_of_three_vertices_with_convex_hulls_raises_config_error(tmp_path):
    """A one-triangle mesh has no convex hull: a ConfigError naming the mesh and link,
    not Coal's bare ValueError."""
    mesh = write_stl(tmp_path / "tri.stl", SQUARE[:1])
    with pytest.raises(ou.ConfigError, match="convex = false") as info:
        ou.load_robot(write_robot(tmp_path, link2=f'<mesh filename="{mesh}"/>'))
    assert str(mesh) in info.value.where and "link2" in info.value.where


BAD_PRIMITIVES = {
    "negative cylinder radius": ('<cylinder radius="-0.065" length="0.2"/>', -0.065),
    "zero cylinder length": ('<cylinder radius="0.03" length="0"/>', 0.0),
    "negative box side": ('<box size="0.1 -0.1 0.1"/>', [0.1, -0.1, 0.1]),
    "zero sphere radius": ('<sphere radius="0"/>', 0.0),
    "zero mesh scale": ("<mesh filename='{mesh}' scale='0 0 0'/>", [0.0, 0.0, 0.0]),
}


@pytest.mark.parametrize(("geometry", "value"), BAD_PRIMITIVES.values(), ids=BAD_PRIMITIVES)
def test_collision_primitive_not_positive_raises_config_error(tmp_path, geometry, value):
    """A collision size that is not positive (Coal builds it, and it never collides) is
    refused, naming the URDF file, the link and the value (convex hulls off: a zero-scale
    mesh is refused before any hull is built)."""
    mesh = write_stl(tmp_path / "box.stl", np.array(SQUARE) + [[[0, 0, 0], [0, 0, 0.1], [0, 0, 0]]])
    with pytest.raises(ou.ConfigError) as info:
        ou.load_robot(write_robot(tmp_path, link1=geometry.format(mesh=mesh), convex=False))
    assert str(tmp_path / "toy.urdf") in info.value.where
    assert "link link1" in info.value.where
    assert info.value.value == value


def test_mirrored_mesh_scale_loads(tmp_path):
    """A negative mesh scale mirrors the mesh (as example-robot-data's TIAGo does): kept."""
    mesh = write_stl(tmp_path / "box.stl", np.array(SQUARE) + [[[0, 0, 0], [0, 0, 0.1], [0, 0, 0]]])
    link1 = f'<mesh filename="{mesh}" scale="-1 -1 -1"/>'
    robot = ou.load_robot(write_robot(tmp_path, link1=link1))
    assert robot.collision_model.ngeoms == 4


def test_joint_limits_reversed_raise_config_error_naming_urdf_joint_and_limits(tmp_path):
    """A joint limit with lower > upper is refused at loading, naming the URDF file, the
    joint and both limits (not blamed on home)."""
    with pytest.raises(ou.ConfigError, match="lower <= upper") as info:
        ou.load_robot(write_robot(tmp_path, a1_limits=(1.0, -1.0)))
    assert str(tmp_path / "toy.urdf") in info.value.where
    assert "joint a1" in info.value.where
    assert info.value.value == {"lower": 1.0, "upper": -1.0}


@pytest.mark.parametrize("frame", ["universe", "base_link"])
def test_palm_frame_no_arm_joint_moves_raises_config_error(tmp_path, frame):
    """A palm frame no arm joint moves (every grasp "out of reach" at planning) is refused
    at loading, naming the robot file's palm_frame."""
    with pytest.raises(ou.ConfigError, match="arm_joints") as info:
        ou.load_robot(write_robot(tmp_path, palm_frame=frame))
    assert info.value.where == "toy.toml: palm_frame"
    assert info.value.value == frame


def test_palm_frame_a_hand_joint_moves_raises_config_error(tmp_path):
    """A palm frame moved by a hand joint (IK places the palm with the hand neutral) is
    refused, naming that joint."""
    with pytest.raises(ou.ConfigError, match="finger") as info:
        ou.load_robot(write_robot(tmp_path, palm_frame="finger_link"))
    assert info.value.where == "toy.toml: palm_frame"


def test_unlisted_joint_held_outside_its_limits_raises_config_error(tmp_path):
    """A joint in neither arm_joints nor hand_joints, held at 0 outside its limits (every
    plan then refused by show and execute), is refused naming it, its limits and 0."""
    with pytest.raises(ou.ConfigError, match=r"\[-3, -0.07\]") as info:
        ou.load_robot(write_robot(tmp_path, extra_limits=(-3.0, -0.07)))
    assert info.value.where == "toy.toml: joint extra"
    assert info.value.value == 0.0


def test_robot_c_outside_limits_names_the_robot_file_and_joint(tmp_path):
    """The robot file's hand.c outside a joint's limits is refused at loading, naming the
    robot file and that joint (not a scene), with the driven values only."""
    with pytest.raises(ou.ConfigError, match="finger = 0.5 outside") as info:
        ou.load_robot(write_robot(tmp_path, c="[0.5]"))
    assert info.value.where == "toy.toml: hand.c"
    assert info.value.value == [0.5]


def test_mimic_offset_outside_limits_names_the_follower(tmp_path):
    """A [mimic] offset setting its follower outside its limits is refused at loading,
    naming the robot file, the follower and its relation; the values shown are c's."""
    tail = '[mimic]\nextra = { joint = "finger", multiplier = 1.0, offset = 100.0 }\n'
    with pytest.raises(ou.ConfigError, match=r"extra \(set by \[mimic\]") as info:
        ou.load_robot(write_robot(tmp_path, tail=tail))
    assert info.value.where == "toy.toml: hand.c"
    assert info.value.value == [0.01]


def test_scene_c_outside_limits_shows_the_driven_values(tmp_path):
    """A [hand] table's c outside the limits is named at its own location with the values
    as given (no mimic followers appended)."""
    tail = '[mimic]\nextra = { joint = "finger", multiplier = 1.0, offset = 0.0 }\n'
    robot = ou.load_robot(write_robot(tmp_path, tail=tail))
    with pytest.raises(ou.ConfigError, match="finger = -1 outside") as info:
        robot.hand_law({"c": [-1.0]}, where="scene.toml: hand")
    assert info.value.where == "scene.toml: hand.c"
    assert info.value.value == [-1.0]


def test_closed_outside_limits_raises_config_error(tmp_path):
    """The robot file's hand.closed outside a joint's limits is refused like c, b and w,
    not clipped."""
    text = write_robot(tmp_path).read_text().replace("mga = 0.25", "mga = 0.25\nclosed = [0.1]")
    (tmp_path / "toy.toml").write_text(text)
    with pytest.raises(ou.ConfigError, match="finger = 0.1 outside") as info:
        ou.load_robot(tmp_path / "toy.toml")
    assert info.value.where == "toy.toml: hand.closed"
