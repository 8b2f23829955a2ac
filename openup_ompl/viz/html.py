"""A self-contained interactive HTML animation of a plan, in MeshCat's three.js viewer.

The robot is loaded by Pinocchio's own ``MeshcatVisualizer`` (its visual meshes, DAE
files with their materials), the scene shapes, the grasp frame and the palm's path are
MeshCat primitives, and the plan is a MeshCat animation: each mesh is sent once and only
the link transforms are keyed per frame, so MeshCat's play / pause / time-scrub controls
work and the file stays small. No MeshCat server runs: the commands a server would relay
are recorded, gzipped and inlined with the viewer bundle shipped in the ``meshcat`` wheel,
so the page needs no network to open.
"""

from __future__ import annotations

import base64
import gzip
import html
import json
import struct
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from openup_ompl._io import make_dir
from openup_ompl._toml import is_finite
from openup_ompl.exceptions import ConfigError, MissingExtra
from openup_ompl.viz._geometry import shape_mesh
from openup_ompl.viz._scene import PlanScene

OBJECT_COLOR = 0xE8871E
OBSTACLE_COLOR = 0xB9A58A
PATH_COLOR = 0x1F77B4


@dataclass(frozen=True)
class HtmlOptions:
    """How the animation plays.

    Attributes:
        fps: Key frames per second of the animation [1/s].
        duration: Time the reach takes in the animation [s].
        hold: Pause at the start and at the grasp [s].
        grasp_axes: Length of the grasp frame's axes [m].
    """

    fps: int = 30
    duration: float = 6.0
    hold: float = 0.8
    grasp_axes: float = 0.08

    def __post_init__(self) -> None:
        for name in ("fps", "duration", "grasp_axes"):
            value = getattr(self, name)
            if not (is_finite(value) and value > 0):
                raise ConfigError(f"html {name}", value, "a positive number")
        if not (is_finite(self.hold) and self.hold >= 0):
            raise ConfigError("html hold", self.hold, "a duration >= 0 [s]")


@dataclass(frozen=True)
class Motion:
    """A recorded motion to animate instead of the plan's rows (a physics rollout).

    Attributes:
        q: ``(K, nq)`` configurations, one per key frame (the plan's joint order).
        object_poses: ``(K, 7)`` object poses ``[x, y, z, qx, qy, qz, qw]`` (world
            frame), or ``None``: the object stays where the scene puts it.
        labels: One line per key frame shown above the readout (phase, time, ...).
        fps: Key frames per second [1/s] (the recording's rate plays it in real time).
        details: The panel's second line.
    """

    q: np.ndarray
    object_poses: np.ndarray | None
    labels: list[str]
    fps: float
    details: str = ""


class _Recorder:
    """Stands in for MeshCat's ZMQ window: keeps each command as the msgpack bytes the
    server would forward to the browser."""

    def __init__(self, umsgpack: Any) -> None:
        self._pack = umsgpack.packb
        self.commands: list[bytes] = []

    def send(self, command: Any) -> None:
        self.commands.append(self._pack(command.lower()))


def _meshcat() -> tuple[Any, Any, Any, Any]:
    try:
        import meshcat
        import meshcat.geometry as mg
        import umsgpack
        from meshcat.animation import Animation
    except ImportError:
        raise MissingExtra("meshcat", "viz") from None
    return meshcat, mg, umsgpack, Animation


def _shape_object(mg: Any, shape: Any) -> tuple[Any, np.ndarray]:
    """A MeshCat geometry of a scene shape and its node transform (4x4, world frame)."""
    transform = shape.placement.homogeneous
    if shape.shape == "box":
        return mg.Box(list(map(float, shape.size))), transform
    if shape.shape == "sphere":
        return mg.Sphere(float(shape.radius)), transform
    if shape.shape == "mesh":
        vertices, triangles = shape_mesh(shape)
        return mg.TriangularMeshGeometry(vertices, triangles), transform
    # three.js cylinders run along their y axis; scene cylinders along z.
    y_to_z = pin.SE3(pin.utils.rotate("x", np.pi / 2), np.zeros(3)).homogeneous
    return mg.Cylinder(float(shape.length), float(shape.radius)), transform @ y_to_z


def _camera(scene: PlanScene) -> dict[str, list[float]]:
    """Camera position and orbit target, in MeshCat's y-up camera frame: the robot's
    joints at the start and at the grasp, the palm's path and the object in view."""
    data = scene.model.createData()
    points = [scene.palm]
    for q in (scene.path[0], scene.path[-1]):
        pin.forwardKinematics(scene.model, data, q)
        points.append(np.array([m.translation for m in data.oMi]))
    if scene.object_name is not None:
        points.append(scene.shapes[-1].placement.translation[None, :])
    cloud = np.vstack(points)
    low, high = cloud.min(axis=0), cloud.max(axis=0)
    target = (low + high) / 2
    # three.js' default camera has a 75 degree vertical field of view.
    distance = 0.8 * float(np.max(high - low)) / np.tan(np.radians(37.5)) + 0.2
    position = target + scene.view_direction() * distance

    def y_up(p: np.ndarray) -> list[float]:
        return [float(p[0]), float(p[2]), float(-p[1])]

    return {"position": y_up(position), "target": y_up(target)}


def _frames(scene: PlanScene, options: HtmlOptions) -> np.ndarray:
    """Path rows shown at each key frame: the reach spread over ``duration``, with
    ``hold`` at both ends."""
    reach = np.linspace(0, len(scene.path) - 1, max(2, round(options.duration * options.fps)))
    hold = round(options.hold * options.fps)
    rows = np.concatenate([np.zeros(hold), reach, np.full(hold, len(scene.path) - 1)])
    return np.round(rows).astype(int)


def _readout(scene: PlanScene, rows: np.ndarray) -> dict[str, Any]:
    """Per key frame values shown live beside the viewer."""
    hand = scene.hand_path[rows]
    sampled = slice(None, None, max(1, len(scene.path) // 400))  # the chart's curve
    return {
        "progress": np.round(scene.progress[rows], 4).tolist(),
        "d": np.round(scene.distances[rows], 4).tolist(),
        "opening": np.round(scene.opening(hand), 4).tolist(),
        "hand": [scene.hand_text(h) for h in hand],
        "mga": scene.law.mga,
        "curve": {
            "progress": np.round(scene.progress[sampled], 4).tolist(),
            "opening": np.round(scene.opening(scene.hand_path[sampled]), 4).tolist(),
        },
    }


def _motion_readout(scene: PlanScene, motion: Motion) -> dict[str, Any]:
    """Per key frame values of a recorded motion: time share, ``d`` of the palm, hand."""
    data = scene.model.createData()
    palms = []
    for q in motion.q:
        pin.framesForwardKinematics(scene.model, data, q)
        palms.append(data.oMf[scene.palm_frame_id].translation.copy())
    start = max(float(np.linalg.norm(scene.palm[0] - scene.grasp.translation)), 1e-12)
    d = np.linalg.norm(np.array(palms) - scene.grasp.translation, axis=1) / start
    hand = motion.q[:, scene.hand_idx]
    progress = np.linspace(0.0, 1.0, len(motion.q))
    opening = scene.opening(hand)
    return {
        "progress": np.round(progress, 4).tolist(),
        "d": np.round(d, 4).tolist(),
        "opening": np.round(opening, 4).tolist(),
        "hand": [scene.hand_text(h) for h in hand],
        "mga": scene.law.mga,
        "labels": list(motion.labels),
        "curve": {
            "progress": np.round(progress, 4).tolist(),
            "opening": np.round(opening, 4).tolist(),
        },
    }


def write_html(
    scene: PlanScene,
    out: str | Path,
    options: HtmlOptions | None = None,
    motion: Motion | None = None,
) -> Path:
    """Write the interactive animation of a plan as one self-contained HTML file.

    Args:
        scene: The plan, loaded (:meth:`PlanScene.from_file`).
        out: HTML file to write.
        options: Timing of the animation.
        motion: A recorded motion (e.g. a physics rollout, with the object moving) to
            animate instead of the plan's rows.

    Returns:
        The HTML file's path.

    Raises:
        MissingExtra: meshcat is not installed.
        ConfigError: The robot's meshes cannot be loaded.
    """
    meshcat, mg, umsgpack, animation_class = _meshcat()
    from pinocchio.visualize import MeshcatVisualizer

    options = options or HtmlOptions()
    recorder = _Recorder(umsgpack)
    viewer = meshcat.Visualizer(window=recorder)
    visual = scene.geometry_model(pin.VISUAL)
    robot = MeshcatVisualizer(scene.model, None, visual)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        robot.initViewer(viewer=viewer)
        robot.loadViewerModel(rootNodeName="robot")
    robot.display(scene.path[0])

    # The page draws a light background behind the transparent canvas.
    viewer["/Background"].set_property("visible", False)
    viewer["/Grid"].set_property("visible", False)
    viewer["/Axes"].set_property("visible", False)
    for shape in scene.shapes:
        is_object = shape.name == scene.object_name
        geometry, transform = _shape_object(mg, shape)
        material = mg.MeshPhongMaterial(color=OBJECT_COLOR if is_object else OBSTACLE_COLOR)
        name = shape.name.replace("/", "_")  # MeshCat paths use "/"
        node = viewer["scene/object" if is_object else f"scene/obstacles/{name}"]
        node.set_object(geometry, material)
        node.set_transform(transform)
    viewer["scene/grasp_frame"].set_object(mg.triad(options.grasp_axes))
    viewer["scene/grasp_frame"].set_transform(scene.grasp.homogeneous)
    palm_path = mg.PointsGeometry(scene.palm.T.astype(np.float32))
    viewer["scene/palm_path"].set_object(
        mg.Line(palm_path, mg.LineBasicMaterial(color=PATH_COLOR, linewidth=2))
    )

    fps: float = options.fps
    if motion is None:
        rows = _frames(scene, options)
        keyed, readout = scene.path[rows], _readout(scene, rows)
    else:
        keyed, readout, fps = motion.q, _motion_readout(scene, motion), motion.fps
    animation = animation_class(default_framerate=fps)
    for key, q in enumerate(keyed):
        with animation.at_frame(viewer, key) as frame:
            robot.viewer = frame
            robot.display(q)
            if motion is not None and motion.object_poses is not None:
                placement = pin.XYZQUATToSE3(motion.object_poses[key])
                frame["scene/object"].set_transform(placement.homogeneous)
    robot.viewer = viewer
    viewer.set_animation(animation, play=True, repetitions=1_000_000)

    blob = b"".join(struct.pack("<I", len(c)) + c for c in recorder.commands)
    bundle = Path(meshcat.__file__).parent / "viewer" / "dist" / "main.min.js"
    law = scene.law
    title = f"{scene.name}: {scene.plan.planner}"
    details = (
        f"u = {law.u:g}, mga = {law.mga:g}"
        + (", fixed hand" if law.fixed is not None else "")
        + f" · seed {scene.plan.seed} · {len(scene.path)} states"
    )
    info = {
        "title": title,
        "details": details if motion is None or not motion.details else motion.details,
        "fps": fps,
        # Key frames of each pause at the ends of a plan's animation (a rollout has none).
        "hold": 0 if motion is not None else round(options.hold * options.fps),
        "camera": _camera(scene),
        "frames": readout,
    }
    page = (
        _PAGE.replace("%TITLE%", html.escape(title))
        .replace("%BUNDLE%", bundle.read_text(encoding="utf-8").replace("</script", "<\\/script"))
        .replace("%COMMANDS%", base64.b64encode(gzip.compress(blob, 9, mtime=0)).decode("ascii"))
        .replace("%INFO%", json.dumps(info).replace("</", "<\\/"))
    )
    out = Path(out)
    make_dir(out.parent)
    out.write_text(page, encoding="utf-8")
    return out


_PAGE = """<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>%TITLE%</title>
<style>
  body { margin: 0; font: 13px/1.35 system-ui, sans-serif; }
  #meshcat-pane { width: 100vw; height: 100vh; overflow: hidden;
                  background: linear-gradient(#fbfcfd, #cfd6e0); }
  #panel { position: absolute; left: 12px; top: 10px; padding: 8px 12px;
           background: rgba(255, 255, 255, 0.88); border-radius: 6px; color: #222;
           box-shadow: 0 1px 4px rgba(0, 0, 0, 0.18); max-width: 330px; }
  #panel b { font-size: 14px; }
  #panel .dim { color: #666; font-size: 12px; }
  #readout { font-variant-numeric: tabular-nums; margin-top: 4px; }
  #chart { display: block; margin-top: 4px; }
</style>
</head>
<body>
<div id="meshcat-pane"></div>
<div id="panel">
  <b id="title"></b><div class="dim" id="details"></div>
  <div id="readout">loading…</div>
  <svg id="chart" width="300" height="70" viewBox="0 0 300 70"></svg>
  <div class="dim">hand opening (c = 0, w = 1) along the reach · controls: top right,
  Animations (play, pause, time)</div>
</div>
<script>
window.addEventListener("error", (e) => {
  document.body.dataset.errors = (document.body.dataset.errors || "") + e.message + "\\n";
});
</script>
<script>%BUNDLE%</script>
<script>
const INFO = %INFO%;
const COMMANDS = "%COMMANDS%";
const viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));

function drawChart() {
  const svg = document.getElementById("chart"), c = INFO.frames.curve, w = 300, h = 70;
  const x = (p) => 4 + p * (w - 8), y = (o) => h - 6 - Math.max(0, Math.min(1, o)) * (h - 14);
  const points = c.progress.map((p, i) => x(p) + "," + y(c.opening[i])).join(" ");
  svg.innerHTML =
    '<rect x="0" y="0" width="300" height="70" fill="#f4f6f9"/>' +
    '<line x1="4" x2="296" y1="' + y(0) + '" y2="' + y(0) + '" stroke="#bbb"/>' +
    '<line x1="4" x2="296" y1="' + y(1) + '" y2="' + y(1) + '" stroke="#ddd"/>' +
    '<polyline fill="none" stroke="#1f77b4" stroke-width="1.6" points="' + points + '"/>' +
    '<line id="cursor" x1="4" x2="4" y1="2" y2="68" stroke="#d62728" stroke-width="1.2"/>';
}

function showFrame() {
  const f = INFO.frames, n = f.d.length;
  const k = Math.max(0, Math.min(n - 1, Math.round(viewer.animator.time * INFO.fps)));
  const mga = f.d[k] <= f.mga ? " (≤ mga)" : "";
  // The slider's time includes a pause at each end: say so, so that the panel and the
  // slider agree (the robot stands at its start for the first pause). A rollout labels
  // its own frames.
  const phase =
    k < INFO.hold ? " (pause at the start)" : k >= n - INFO.hold ? " (at the grasp)" : "";
  const where = f.labels ? f.labels[k] :
    "t = " + viewer.animator.time.toFixed(2) + " s" + phase + " · reach " +
    Math.round(100 * f.progress[k]) + " %";
  document.getElementById("readout").textContent = where + " · d = " + f.d[k].toFixed(2) + mga +
    " · hand " + f.hand[k] + " (" + Math.round(100 * f.opening[k]) + " % of c → w)";
  const cursor = document.getElementById("cursor");
  const x = 4 + f.progress[k] * 292;
  cursor.setAttribute("x1", x);
  cursor.setAttribute("x2", x);
  requestAnimationFrame(showFrame);
}

async function load() {
  const raw = Uint8Array.from(atob(COMMANDS), (ch) => ch.charCodeAt(0));
  const stream = new Blob([raw]).stream().pipeThrough(new DecompressionStream("gzip"));
  const bytes = new Uint8Array(await new Response(stream).arrayBuffer());
  const view = new DataView(bytes.buffer);
  let at = 0, count = 0;
  while (at < bytes.length) {
    const size = view.getUint32(at, true);
    viewer.handle_command_bytearray(bytes.slice(at + 4, at + 4 + size));
    at += 4 + size;
    count += 1;
  }
  const cam = INFO.camera;
  viewer.camera.position.set(...cam.position);
  viewer.controls.target.set(...cam.target);
  viewer.controls.update();
  viewer.set_dirty();
  viewer.gui.open();
  const scene = viewer.gui.__folders["Scene"];
  if (scene) scene.close();
  document.getElementById("title").textContent = INFO.title;
  document.getElementById("details").textContent = INFO.details;
  drawChart();
  requestAnimationFrame(showFrame);
  document.body.dataset.commands = count;
  document.body.dataset.state = "ready";
}
load().catch((e) => {
  document.body.dataset.errors = (document.body.dataset.errors || "") + e + "\\n";
  document.getElementById("readout").textContent = "could not load the scene: " + e;
});
</script>
</body>
</html>
"""
