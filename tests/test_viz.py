"""Pictures of a plan: `show` (HTML animation, storyboard, Fig. 3), `law`, and the demo.

The HTML is opened in headless Chromium (Debian's `chromium`, software WebGL) and the
screenshot checked for a rendered scene; PNGs are checked for size and content.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import openup_ompl as ou
from openup_ompl.exceptions import MissingExtra
from openup_ompl.viz import PlanScene
from openup_ompl.viz._geometry import box_mesh, decimate, revolution_mesh
from openup_ompl.viz.storyboard import frame_rows

Image = pytest.importorskip("PIL.Image", reason="pillow comes with matplotlib (viz extra)")


def run_cli(*args: str, cwd: Path, prelude: str = "") -> subprocess.CompletedProcess[str]:
    """Run the command line in a subprocess (after ``prelude``, Python code) in ``cwd``."""
    code = f"{prelude}\nfrom openup_ompl.__main__ import run\nrun()"
    return subprocess.run(
        [sys.executable, "-c", code, *args],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=cwd,
    )


def pixels(path: Path) -> np.ndarray:
    """The PNG's RGB pixels, ``(height, width, 3)`` integers."""
    with Image.open(path) as image:
        return np.asarray(image.convert("RGB")).astype(int)


def distinct_colors(rgb: np.ndarray) -> int:
    return len(np.unique(rgb.reshape(-1, 3), axis=0))


@pytest.fixture(scope="module")
def plan_file(tmp_path_factory) -> Path:
    """A plan of the default scene (IKBiRRT, seed 3), saved as reach.json."""
    setup = ou.GraspPlanningSetup(ou.load_scene(ou.default_scene_path()), u=0.3)
    plan = setup.solve(time_limit=20.0, planner="ikbirrt", seed=3)
    return plan.save(tmp_path_factory.mktemp("plan") / "reach.json")


@pytest.fixture(scope="module")
def shown(plan_file, tmp_path_factory) -> tuple[subprocess.CompletedProcess[str], Path]:
    """`show reach.json --out pictures` run once."""
    out = tmp_path_factory.mktemp("show") / "pictures"
    result = run_cli("show", str(plan_file), "--out", str(out), cwd=out.parent)
    return result, out


def test_show_writes_the_three_pictures_and_says_where(shown):
    """`show` exits 0 and prints the HTML, storyboard and Fig. 3 files it wrote."""
    result, out = shown
    assert result.returncode == 0, result.stderr
    assert result.stderr == ""
    for name in ("reach.html", "reach_storyboard.png", "reach_hand_law.png"):
        assert (out / name).is_file()
        assert str(out / name) in result.stdout


def test_html_is_self_contained_and_small(shown):
    """The HTML loads nothing from the network and stays well under 20 MB."""
    _, out = shown
    page = (out / "reach.html").read_text(encoding="utf-8")
    assert len(page.encode()) < 20e6
    assert not re.search(r"""(src|href)\s*=\s*["']?\s*(https?:)?//""", page, re.IGNORECASE)
    assert not re.search(r"""url\(\s*["']?\s*(https?:)?//""", page, re.IGNORECASE)
    # The only absolute URLs are XML namespace names in the three.js bundle.
    urls = set(re.findall(r"https?://[^\s\"'<>)]+", page))
    assert urls <= {"http://www.w3.org/1999/xhtml"}, urls


def _chromium() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        found = shutil.which(name)
        if found:
            return found
    if os.environ.get("CI"):
        pytest.fail("chromium is missing in CI: .ci/run installs Debian's chromium package")
    pytest.skip("no chromium on this machine (apt-get install chromium)")


def _headless(page: Path, tmp_path: Path, *args: str) -> subprocess.CompletedProcess[str]:
    """Open ``page`` in headless Chromium with software WebGL (SwiftShader)."""
    command = [
        _chromium(),
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        f"--user-data-dir={tmp_path / 'profile'}",
        "--use-angle=swiftshader",
        "--enable-unsafe-swiftshader",
        "--window-size=1280,800",
        "--virtual-time-budget=15000",
        *args,
        page.resolve().as_uri(),
    ]
    return subprocess.run(command, capture_output=True, text=True, timeout=180)


@pytest.mark.slow
def test_html_renders_the_scene_in_headless_chromium(shown, tmp_path):
    """Chromium renders the robot (its dark joint covers) and the orange object, not a
    blank page, and the page reports no script error."""
    _, out = shown
    page = out / "reach.html"
    shot = tmp_path / "shot.png"
    result = _headless(page, tmp_path, f"--screenshot={shot}")
    assert shot.is_file(), result.stderr[-2000:]
    rgb = pixels(shot)
    assert rgb.shape[:2] == (800, 1280)
    scene = rgb[200:, :1000]  # below the info panel, left of MeshCat's controls
    red, green, blue = scene[..., 0], scene[..., 1], scene[..., 2]
    orange = (red > 180) & (green > 80) & (green < 170) & (blue < 90)
    dark = scene.max(axis=-1) < 70
    assert distinct_colors(scene) > 500
    assert orange.sum() > 200, "the object is not drawn"
    assert dark.sum() > 200, "the robot is not drawn"

    dom = _headless(page, tmp_path, "--dump-dom").stdout
    assert 'data-state="ready"' in dom
    assert "data-errors" not in dom


@pytest.mark.parametrize(
    ("name", "min_width"), [("reach_storyboard.png", 1500), ("reach_hand_law.png", 1000)]
)
def test_pngs_have_size_and_content(shown, name, min_width):
    """The storyboard and Fig. 3 PNGs are large, varied pictures, small enough for a README."""
    _, out = shown
    path = out / name
    assert 20e3 < path.stat().st_size < 1e6
    rgb = pixels(path)
    assert rgb.shape[1] >= min_width and rgb.shape[0] >= 400
    assert distinct_colors(rgb) > 200
    assert rgb.std() > 10


def test_plan_scene_follows_the_plan(plan_file):
    """Loaded from the file alone, d runs from 1 to ~0 and every hand row is the law at d."""
    scene = PlanScene.from_file(plan_file)
    assert scene.distances[0] == pytest.approx(1.0)
    assert scene.distances[-1] < 0.01
    assert scene.progress[0] == 0.0 and scene.progress[-1] == pytest.approx(1.0)
    np.testing.assert_allclose(scene.hand_path, scene.law.batch(scene.distances), atol=1e-9)
    assert scene.object_name == "can"
    assert scene.prismatic.all()


def test_storyboard_frames_start_reach_mga_and_end_at_the_grasp(plan_file):
    """The storyboard shows the start, the grasp and the first state at d <= mga."""
    scene = PlanScene.from_file(plan_file)
    rows = frame_rows(scene, 6)
    assert rows[0] == 0 and rows[-1] == len(scene.path) - 1
    assert scene.mga_row in rows
    assert rows == sorted(set(rows))


@pytest.mark.parametrize("count", [2, 3])
def test_storyboard_of_two_or_three_frames(plan_file, count):
    """The documented minimum of 2 frames shows the start and the grasp (it crashed when
    the mga row lay inside the path); from 3 on the mga row replaces an inner frame."""
    scene = PlanScene.from_file(plan_file)
    assert 0 < scene.mga_row < len(scene.path) - 1
    rows = frame_rows(scene, count)
    assert rows[0] == 0 and rows[-1] == len(scene.path) - 1 and len(rows) == count
    assert (scene.mga_row in rows) is (count > 2)


@pytest.mark.parametrize(
    ("field", "value"),
    [("frames", 1), ("frames", 2.5), ("frames", 10**9), ("dpi", 0), ("panel_size", "a"),
     ("closeup", "no"), ("mesh_cell", float("nan"))],
)  # fmt: skip
def test_bad_storyboard_options_are_named(field, value):
    """Each StoryboardOptions field is checked where it is given, naming it."""
    from openup_ompl.viz.storyboard import StoryboardOptions

    with pytest.raises(ou.ConfigError, match=f"storyboard {field}"):
        StoryboardOptions(**{field: value})


def test_law_command_writes_a_png(tmp_path):
    """`law --robot panda --u 0 0.3 1 --out law.png` writes a figure of the law."""
    result = run_cli(
        "law", "--robot", "panda", "--u", "0", "0.3", "1", "--out", "law.png", cwd=tmp_path
    )
    assert result.returncode == 0, result.stderr
    assert "law.png" in result.stdout
    rgb = pixels(tmp_path / "law.png")
    assert rgb.shape[1] >= 800
    assert distinct_colors(rgb) > 100


def test_law_of_a_scene_uses_its_hand_overrides(tmp_path):
    """`law --scene` draws the scene's c, b, w (the default scene's c is 35 mm)."""
    result = run_cli("law", "--scene", str(ou.default_scene_path()), cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "panda_hand_law.png").is_file()


def test_demo_writes_its_pictures_next_to_its_plan(tmp_path):
    """`demo` writes plan.json, plan.html and both PNGs in its directory and says where."""
    result = run_cli("demo", "--out", "demo", "--seed", "2", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    for name in ("plan.json", "plan.html", "plan_storyboard.png", "plan_hand_law.png"):
        assert (tmp_path / "demo" / name).is_file()
        assert f"demo/{name}" in result.stdout


@pytest.mark.parametrize("module", ["meshcat", "matplotlib"])
def test_missing_extra_exits_2_with_the_install_hint(plan_file, tmp_path, module):
    """Without meshcat or matplotlib, `show` exits 2 with one line naming the extra."""
    prelude = f"import sys; sys.modules[{module!r}] = None"
    result = run_cli("show", str(plan_file), "--out", "out", cwd=tmp_path, prelude=prelude)
    assert result.returncode == 2
    assert result.stderr.splitlines() == [
        f"openup-ompl: error: {module} is needed for this: pip install 'openup-ompl[viz]'"
    ]


def test_missing_extra_is_a_typed_import_error(plan_file, tmp_path, monkeypatch):
    """Without meshcat, write_html raises MissingExtra, an OpenUpError and an ImportError."""
    from openup_ompl.viz import write_html

    scene = PlanScene.from_file(plan_file)
    monkeypatch.setitem(sys.modules, "meshcat", None)
    with pytest.raises(MissingExtra, match=r"openup-ompl\[viz\]") as caught:
        write_html(scene, tmp_path / "x.html")
    assert isinstance(caught.value, ou.OpenUpError)
    assert isinstance(caught.value, ImportError)


def _broken(plan: dict, what: str) -> dict:
    if what == "format":
        plan["format"] = "something/2"
    elif what == "urdf":
        plan["robot"]["urdf"] = "/nonexistent/robot.urdf"
    elif what == "hand_law":
        del plan["hand_law"]["mga"]
    elif what == "package_dirs":
        plan["robot"]["package_dirs"] = []
    return plan


@pytest.mark.parametrize(
    ("what", "named"),
    [
        ("not json", "plan file"),
        ("format", "something/2"),
        ("urdf", "/nonexistent/robot.urdf"),
        ("hand_law", "hand_law.mga"),
        ("package_dirs", "robot.package_dirs"),
    ],
)
def test_bad_plan_file_exits_2_naming_the_fault(plan_file, tmp_path, what, named):
    """A plan file that is not JSON, of another format, naming a missing URDF, lacking a
    law parameter or the meshes' package directories exits 2 with one line naming it;
    nothing is written."""
    bad = tmp_path / "bad.json"
    if what == "not json":
        bad.write_text("{ not json")
    else:
        bad.write_text(json.dumps(_broken(json.loads(plan_file.read_text()), what)))
    result = run_cli("show", str(bad), "--out", "out", cwd=tmp_path)
    assert result.returncode == 2
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and named in lines[0], result.stderr
    assert not (tmp_path / "out").exists()


def test_box_mesh_has_the_box_area():
    """A tessellated box (faces cut to 5 cm) has the box's surface area."""
    vertices, faces = box_mesh(np.array([0.3, 0.2, 0.1]), max_edge=0.05)
    tris = vertices[faces]
    area = 0.5 * np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=1)
    assert area.sum() == pytest.approx(2 * (0.3 * 0.2 + 0.2 * 0.1 + 0.3 * 0.1))
    assert np.max(np.abs(vertices), axis=0) == pytest.approx([0.15, 0.1, 0.05])


def test_decimated_mesh_keeps_the_silhouette():
    """Vertex clustering drops triangles and moves no vertex farther than one cell."""
    profile = np.stack([np.full(50, 0.05), np.linspace(-0.1, 0.1, 50)], axis=1)
    vertices, faces = revolution_mesh(profile, segments=64)
    coarse, coarse_faces = decimate((vertices, faces), cell=0.01)
    assert len(coarse_faces) < len(faces) / 4
    radius = np.linalg.norm(coarse[:, :2], axis=1)
    assert np.all(np.abs(radius - 0.05) < 0.01 * np.sqrt(3))


def test_show_refuses_what_it_cannot_draw_or_write(plan_file, tmp_path):
    """``show`` of a Plan object (it takes a file), an output directory that is a file,
    or options of another type: a ConfigError before anything is written (a TypeError,
    FileExistsError or AttributeError before)."""
    from openup_ompl.viz import show

    (tmp_path / "afile").write_text("")
    plan = ou.GraspPlanningSetup(ou.load_scene(ou.default_scene_path())).solve(seed=1)
    cases = [
        ({"plan": plan}, "plan: got 'Plan'"),
        ({"plan": plan_file, "out_dir": tmp_path / "afile"}, "afile is a file"),
        ({"plan": plan_file, "out_dir": tmp_path, "html": "x"}, "html"),
        ({"plan": plan_file, "out_dir": tmp_path, "storyboard": "x"}, "storyboard"),
    ]
    for kwargs, named in cases:
        with pytest.raises(ou.ConfigError, match=named):
            show(**kwargs)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]
    with pytest.raises(ou.ConfigError, match="afile is a file"):
        plan.save(tmp_path / "afile" / "plan.json")


def _law(c: list[float], b: list[float], w: list[float]) -> ou.HandLaw:
    n = len(c)
    return ou.HandLaw(
        np.array(c), np.array(b), np.array(w), 0.3, 0.25, np.full(n, -3.0), np.full(n, 3.0)
    )


def test_fig3_labels_of_close_levels_are_merged():
    """c, b, w lines closer than 4 % of the axis share one label (``b = w`` when equal), so
    that no two labels overlap; distant levels keep their own."""
    import matplotlib.pyplot as plt

    from openup_ompl.viz.law import _references

    law = _law([0.0, 0.0, 0.0], [1.0, 0.5, 1.0], [1.0, 0.9, 1.02])
    labels = []
    for j in range(3):
        fig, ax = plt.subplots()
        ax.set_ylim(-10.0, 100.0)  # 4 % of it: 4.4 units, 0.088 joint units at scale 50
        _references(ax, law, j, 50.0)
        labels.append(sorted(text.get_text().strip() for text in ax.texts))
        plt.close(fig)
    assert labels == [["b = w", "c"], ["b", "c", "w"], ["b, w", "c"]]


def test_fig3_gives_held_joints_no_panel():
    """A joint the law holds (c = b = w) gets no panel of its own; if the law holds every
    joint, every joint is drawn."""
    from openup_ompl.viz.law import _groups, _moving

    law = _law([0.2, 0.0, 0.1], [0.5, 0.0, 0.1], [0.9, 0.0, 0.4])
    moving, held = _moving(law, _groups(np.vstack([law.c, law.b, law.w])))
    assert moving == [[0], [2]] and held == [[1]]
    still = _law([0.1, 0.1], [0.1, 0.1], [0.1, 0.1])
    assert _moving(still, [[0, 1]]) == ([[0, 1]], [])


def test_storyboard_titles_explain_d_above_one(plan_file):
    """A frame whose d exceeds 1 says that the palm is farther than at the start."""
    from openup_ompl.viz.storyboard import _title

    scene = PlanScene.from_file(plan_file)
    scene.distances[1] = 1.4
    assert "farther than at the start" in _title(scene, 1)
    scene.distances[1] = 0.6
    assert "farther" not in _title(scene, 1)
