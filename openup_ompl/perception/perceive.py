"""One perception step: view -> noisy cloud -> superquadric fit -> object pose and ``u``.

The outputs of ``openup-ompl perceive`` are written here too: the cloud (NPZ), a summary
(``perception.json``) and ``perceived.toml``, the scene with the object at the estimate
and ``[hand] u`` from :func:`~openup_ompl.perception.uncertainty.u_from_covariance`.
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from openup_ompl import _toml
from openup_ompl._io import make_dir, write_atomic
from openup_ompl.exceptions import (
    ConfigError,
    DegenerateFit,
    InvalidProblem,
    ObjectCutOff,
    ObjectNotVisible,
    ObjectOccluded,
    TooFewPoints,
)
from openup_ompl.perception.camera import (
    CameraOptions,
    DepthCamera,
    DepthView,
    camera_of_scene,
)
from openup_ompl.perception.noise import NoiseOptions, PointCloud, noisy_cloud, normal_sigma
from openup_ompl.perception.superquadric import (
    N_PARAMETERS,
    FitOptions,
    Silhouette,
    SuperquadricFit,
    fit_superquadric,
)
from openup_ompl.perception.uncertainty import u_from_covariance
from openup_ompl.scene import Problem, Shape

__all__ = [
    "Perception",
    "at_estimate",
    "estimated_pose",
    "occluded_outline",
    "perceive",
    "perceived_toml",
    "silhouette_of",
    "write_perception",
]


@dataclass(frozen=True)
class Perception:
    """What one view tells about the object.

    Attributes:
        cloud: The object's measured points.
        fit: The superquadric fit and its covariance.
        pose: The object's estimated pose ``[x, y, z, qx, qy, qz, qw]`` (world frame), in
            the scene shape's own frame (:func:`estimated_pose`).
        u: The hand law's ``u`` from the covariance.
        camera: Camera position [m].
        target: The point [m] it looked at.
    """

    cloud: PointCloud
    fit: SuperquadricFit
    pose: np.ndarray
    u: float
    camera: np.ndarray
    target: np.ndarray

    def summary(self) -> dict[str, Any]:
        """The estimate as plain JSON-ready values."""
        sq = self.fit.superquadric
        return {
            "pose": [float(x) for x in self.pose],
            "u": self.u,
            "points": self.fit.points,
            "dropped": self.cloud.dropped,
            "sizes": sq.sizes.tolist(),
            "exponents": sq.exponents.tolist(),
            "diameter": self.fit.diameter,
            "mean_residual": self.fit.mean_residual,
            "residual_rms": self.fit.residual_rms,
            "position_covariance": self.fit.position_covariance.tolist(),
            "rotation_covariance": self.fit.rotation_covariance.tolist(),
            "camera": self.camera.tolist(),
            "target": self.target.tolist(),
        }


def silhouette_of(
    view: DepthView, noise: NoiseOptions, camera: CameraOptions, support: float | None = None
) -> Silhouette:
    """The view's free space: the object's pixels, pixels without a measurement (dropped
    or no hit: unknown) and pixels whose hit lies in front of the object are allowed;
    nothing below the ``support``'s height [m] (:meth:`DepthCamera.support_under`)."""
    valid = _valid(view, noise)
    shape = (view.height, view.width)
    return Silhouette.from_view(
        (view.on_object & valid).reshape(shape),
        (_occluder(view, noise) | ~valid).reshape(shape),
        view.position,
        view.rotation,
        camera.intrinsics(),
        support=support,
    )


def _valid(view: DepthView, noise: NoiseOptions) -> np.ndarray:
    """The pixels measured (a hit, not at grazing incidence)."""
    return np.asarray(view.hit & (view.incidence <= math.radians(noise.max_incidence)))


def _occluder(view: DepthView, noise: NoiseOptions) -> np.ndarray:
    """The measured pixels off the object nearer than its nearest point: what may hide
    part of it."""
    valid = _valid(view, noise)
    on_object = view.on_object & valid
    front = np.nanmin(view.depth[on_object]) if on_object.any() else np.inf
    return np.asarray(valid & ~view.on_object & (view.depth < front))


#: Image sides and the step (row, column) to the pixel beyond each.
_SIDES = {"top": (-1, 0), "bottom": (1, 0), "left": (0, -1), "right": (0, 1)}


def occluded_outline(view: DepthView, noise: NoiseOptions) -> dict[str, tuple[int, int]]:
    """Per image side, the object's outline pixels on it whose next pixel beyond is an
    occluder (a measured surface nearer than the object's nearest point), and all its
    outline pixels on it: ``{side: (hidden, outline)}``. The table in front of a standing
    object's base lies behind its nearest point and hides nothing."""
    shape = (view.height, view.width)
    on_object = view.on_object.reshape(shape)
    occluder = _occluder(view, noise).reshape(shape)
    counts = {}
    for side, (dr, dc) in _SIDES.items():
        # beyond[r, c]: the pixel (r + dr, c + dc), False off the image.
        inside = np.zeros(shape, dtype=bool)
        hidden = np.zeros(shape, dtype=bool)
        rows = slice(max(-dr, 0), shape[0] - max(dr, 0))
        cols = slice(max(-dc, 0), shape[1] - max(dc, 0))
        beyond_rows = slice(max(dr, 0), shape[0] + min(dr, 0))
        beyond_cols = slice(max(dc, 0), shape[1] + min(dc, 0))
        inside[rows, cols] = on_object[beyond_rows, beyond_cols]
        hidden[rows, cols] = occluder[beyond_rows, beyond_cols]
        outline = on_object & ~inside
        counts[side] = (int(np.count_nonzero(outline & hidden)), int(np.count_nonzero(outline)))
    return counts


#: An image side is hidden when more than this share of the object's outline on it lies
#: next to an occluder (:func:`occluded_outline`).
HIDDEN_SHARE = 0.5


#: A fitted half-size within this factor of ``FitOptions.min_size`` is a collapsed fit
#: (:class:`DegenerateFit`). The closed loops' views fit half-sizes of 17 mm and more;
#: a camera 75 degrees above the LWA3's can fits 2.0 mm, its centre 79 mm too high.
DEGENERATE_FACTOR = 1.5


#: The largest ratio of a superquadric's ``a1``, ``a2`` that still reads as a round
#: section about its z (:func:`_cylinder_axis`).
ROUND_SECTION = 1.25
#: The weight of the scene's axis in :func:`_cylinder_axis` against the half-sizes' log
#: ratios: a tie-breaker (a can of 47 x 23 x 21 mm half-sizes reads 0.87 along its long
#: axis against 1.77 across it).
AXIS_PRIOR = 0.2


def perceive(
    problem: Problem,
    camera: CameraOptions | None = None,
    noise: NoiseOptions | None = None,
    fit: FitOptions | None = None,
    *,
    rng: np.random.Generator | None = None,
    depth_camera: DepthCamera | None = None,
    silhouette: bool = True,
    weighted: bool = True,
) -> Perception:
    """Look at the scene's object once, fit it, and choose ``u``.

    Args:
        problem: The scene; its object is where it truly is.
        camera: Camera options (ignored if ``depth_camera`` is given); ``None``: the
            scene file's ``[camera]`` table, as ``openup-ompl perceive`` reads it
            (:func:`~openup_ompl.perception.camera.camera_of_scene`).
        noise: Sensor noise model.
        fit: Superquadric fit options.
        rng: The noise's random generator (default: seed 0).
        depth_camera: An already built camera (many views of one scene).
        silhouette: Use the view's free space in the fit (:class:`Silhouette`), and the
            surface under the object as its floor (it stands on the table, not through it).
        weighted: Weight the fit by the sensor's noise model (:func:`normal_sigma`).

    Raises:
        ConfigError: ``depth_camera`` was built on another object (or pose) than the
            problem's.
        ObjectNotVisible: No point of the object is measured.
        TooFewPoints: Too few for the fit.
        ObjectCutOff: The object's pixels reach the image border (the view does not
            bound it).
        ObjectOccluded: More than :data:`HIDDEN_SHARE` of the object's outline on one
            image side lies next to a nearer surface (:func:`occluded_outline`), and
            nothing else bounds it there (the bottom of an object standing on a surface
            the rays find does not count).
        DegenerateFit: The fit collapsed onto one face (a half-size within
            :data:`DEGENERATE_FACTOR` of its lower bound).
    """
    noise = noise or NoiseOptions()
    rng = rng if rng is not None else np.random.default_rng(0)
    if depth_camera is None and camera is None:
        camera = camera_of_scene(problem)
    if depth_camera is not None and not _same_object(depth_camera.problem, problem):
        # Its scene is its own: it would measure that scene's object, reported as this one.
        theirs, ours = (getattr(q.object, "name", None) for q in (depth_camera.problem, problem))
        raise ConfigError(
            "depth_camera",
            f"a camera on {theirs!r}",
            f"a DepthCamera built on this problem's object ({ours!r}, at the same pose)",
        )
    cam = depth_camera or DepthCamera(problem, camera)
    view = cam.render()
    cloud = noisy_cloud(view, noise, rng)
    assert problem.object is not None
    if cloud.points.shape[0] == 0:
        raise ObjectNotVisible(
            cam.position.tolist(),
            cam.target.tolist(),
            problem.object.name,
            int(view.hit.sum()),
            cloud.dropped,
        )
    if cloud.points.shape[0] < 2 * N_PARAMETERS:
        raise TooFewPoints(cloud.points.shape[0], 2 * N_PARAMETERS)
    on_object = view.on_object.reshape(view.height, view.width)
    border = {
        "top": on_object[0],
        "bottom": on_object[-1],
        "left": on_object[:, 0],
        "right": on_object[:, -1],
    }
    sides = [side for side, pixels in border.items() if pixels.any()]
    if sides:
        # The corner pixels lie on two sides: count each pixel once.
        edge = on_object.copy()
        edge[1:-1, 1:-1] = False
        raise ObjectCutOff(int(edge.sum()), sides)
    support = cam.support_under(cloud.points, view) if silhouette else None
    hidden = {
        side: count
        for side, (count, outline) in occluded_outline(view, noise).items()
        if count > HIDDEN_SHARE * outline and not (side == "bottom" and support is not None)
    }
    if hidden:
        raise ObjectOccluded(sum(hidden.values()), list(hidden))
    shape = silhouette_of(view, noise, cam.options, support) if silhouette else None
    weights = normal_sigma(cam.position, cam.rotation, noise) if weighted else None
    result = fit_superquadric(cloud.points, fit, shape, weights)
    bound = (fit or FitOptions()).min_size
    if float(np.min(result.superquadric.sizes)) <= DEGENERATE_FACTOR * bound:
        raise DegenerateFit(result.superquadric.sizes.tolist(), bound)
    pose = estimated_pose(result, problem.object)
    u = u_from_covariance(
        result.position_covariance,
        result.rotation_covariance,
        problem,
        sizes=result.superquadric.sizes,
    )
    return Perception(cloud, result, pose, u, cam.position.copy(), cam.target.copy())


def _same_object(a: Problem, b: Problem) -> bool:
    """Whether two problems hold the same object at the same pose (the camera's scene)."""
    if a is b:
        return True
    if a.object is None or b.object is None:
        return a.object is b.object
    return a.object.to_table() == b.object.to_table()


def estimated_pose(fit: SuperquadricFit, nominal: Shape) -> np.ndarray:
    """The fitted pose in the frame of the scene's shape.

    The superquadric's frame is one of several equivalent ones: a box's axes may be
    permuted and flipped, a cylinder's axis flipped and its yaw about the axis is
    unobservable, a sphere's orientation is. Among the equivalent orientations the one
    closest to the scene's nominal orientation is returned (harmless: they describe the
    same solid). A box's axes are matched to the scene's sizes by the fitted half-sizes'
    order.
    """
    sq = fit.superquadric
    rotation = sq.rotation
    reference = pin.XYZQUATToSE3(nominal.pose).rotation
    if nominal.shape == "sphere":
        rotation = reference
    elif nominal.shape == "cylinder":
        assert nominal.radius is not None and nominal.length is not None
        column = _cylinder_axis(
            sq.sizes, sq.exponents, nominal.radius, nominal.length / 2, rotation.T @ reference[:, 2]
        )
        axis = rotation[:, column] * np.sign(rotation[:, column] @ reference[:, 2] or 1.0)
        turn = _rotation_between(reference[:, 2], axis)
        rotation = turn @ reference
    else:
        assert nominal.size is not None
        order = np.argsort(sq.sizes)[np.argsort(np.argsort(np.asarray(nominal.size)))]
        permuted = rotation[:, order]
        best, best_angle = permuted, np.inf
        for signs in ((1, 1, 1), (1, -1, -1), (-1, 1, -1), (-1, -1, 1)):
            candidate = permuted * np.array(signs, dtype=float)
            if np.linalg.det(candidate) < 0:
                candidate = candidate * np.array([1.0, 1.0, -1.0])
            angle = float(np.linalg.norm(pin.log3(reference.T @ candidate)))
            if angle < best_angle:
                best, best_angle = candidate, angle
        rotation = best
    return np.asarray(pin.SE3ToXYZQUAT(pin.SE3(rotation, sq.position)), dtype=float)


def _cylinder_axis(
    sizes: np.ndarray,
    exponents: np.ndarray,
    radius: float,
    half_length: float,
    nominal_axis: np.ndarray,
) -> int:
    """Which of the superquadric's axes is the cylinder's. Its own z when it is shaped as
    a cylinder about z (a round section, ``e2`` >= 0.5, between flat ends, ``e1`` <= 0.5,
    and ``a1``, ``a2`` within :data:`ROUND_SECTION` of each other). Otherwise the axis
    whose half-size, with the other two as radii, is the nearest to the nominal cylinder's
    (by ratio): the fit starts from every principal axis of the cloud, and a superquadric
    lying across an upright can fits a partial view about as well as one along it. A can
    as long as it is wide leaves the sizes no say: :data:`AXIS_PRIOR` times the sine of
    each axis's angle to the scene's ``nominal_axis`` (in the superquadric's frame) then
    decides."""
    e1, e2 = exponents
    if e2 >= 0.5 and e1 <= 0.5 and max(sizes[:2]) <= ROUND_SECTION * min(sizes[:2]):
        return 2
    mismatch = [
        abs(math.log(sizes[k] / half_length))
        + sum(abs(math.log(sizes[j] / radius)) for j in range(3) if j != k)
        + AXIS_PRIOR * math.sqrt(max(0.0, 1.0 - float(nominal_axis[k]) ** 2))
        for k in range(3)
    ]
    return int(np.argmin(mismatch))


def _rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation taking unit vector ``a`` onto unit vector ``b``."""
    axis = np.cross(a, b)
    sine, cosine = float(np.linalg.norm(axis)), float(a @ b)
    if sine < 1e-12:
        return np.eye(3)  # parallel (antiparallel is excluded by the sign choice)
    return np.asarray(pin.exp3(axis / sine * math.atan2(sine, cosine)))


def at_estimate(problem: Problem, pose: np.ndarray) -> Problem:
    """The problem as perception reports it: the object at ``pose`` and the grasp pose
    carried along (``T_grasp' = T_estimate T_nominal^-1 T_grasp``).

    Raises:
        InvalidProblem: The problem has no object.
        ConfigError: ``pose`` is not ``[x, y, z, qx, qy, qz, qw]`` of finite numbers with a
            unit quaternion (normalised).
    """
    shape = problem.object
    if shape is None:
        raise InvalidProblem("the scene has no [object]")
    pose = _toml.pose(pose, "pose")
    moved = pin.XYZQUATToSE3(pose) * shape.placement.inverse()
    grasp = np.asarray(pin.SE3ToXYZQUAT(moved * problem.grasp), dtype=float)
    return dataclasses.replace(problem, object=shape.at(pose), grasp_pose=grasp)


def perceived_toml(problem: Problem, perception: Perception) -> str:
    """The scene file with ``[object] pose`` at the estimate, ``[grasp] pose`` carried
    along with it (:func:`at_estimate`: the grasp is defined relative to the object) and
    ``[hand] u`` set; a robot named by a relative path is written as an absolute one, so
    that the file plans from any directory.

    Raises:
        InvalidProblem: The problem has no object or was not loaded from a scene file.
    """
    from openup_ompl.perception._toml_writer import dumps
    from openup_ompl.robot import available_robots

    if problem.path is None:
        raise InvalidProblem("the problem was not loaded from a scene file: nothing to rewrite")
    raw = _toml.read_toml(problem.path, "scene file")
    if raw["robot"] not in available_robots():
        raw["robot"] = str(problem.robot.spec.path)
    raw["object"] = {**raw["object"], "pose": [round(float(x), 9) for x in perception.pose]}
    raw["hand"] = {**raw.get("hand", {}), "u": round(perception.u, 6)}
    grasp = at_estimate(problem, perception.pose).grasp_pose
    raw["grasp"] = {**raw["grasp"], "pose": [round(float(x), 9) for x in grasp]}
    fit = perception.fit
    header = (
        f"# Perceived by openup-ompl perceive from {problem.path.name}: {fit.points} points,"
        f" superquadric sizes {np.round(fit.superquadric.sizes, 4).tolist()} m,"
        f" exponents {np.round(fit.superquadric.exponents, 3).tolist()},\n"
        f"# mean residual {fit.mean_residual * 1e3:.2f} mm; u = {perception.u:.3f} from the"
        " pose covariance (openup_ompl.perception.uncertainty); the grasp pose moved with"
        " the object's estimate.\n"
    )
    return header + dumps(raw)


def write_perception(problem: Problem, perception: Perception, out: str | Path) -> dict[str, Path]:
    """Write ``cloud.npz``, ``perception.json`` and ``perceived.toml`` into the directory
    ``out`` (created if missing); returns their paths.

    Raises:
        InvalidProblem: ``problem`` has no object (its true pose is written beside the
            perceived one), or was not loaded from a scene file (``perceived.toml`` is
            that file rewritten).
        ConfigError: ``out`` is an existing file.
    """
    if problem.object is None:
        raise InvalidProblem("the scene has no [object]")
    if problem.path is None:
        raise InvalidProblem("the problem was not loaded from a scene file: nothing to rewrite")
    out = make_dir(Path(out))
    paths = {
        "cloud": out / "cloud.npz",
        "summary": out / "perception.json",
        "scene": out / "perceived.toml",
    }
    np.savez(
        paths["cloud"],
        points=perception.cloud.points,
        pixels=perception.cloud.pixels,
        sigma_axial=perception.cloud.sigma_axial,
        sigma_lateral=perception.cloud.sigma_lateral,
        scene_points=perception.cloud.scene_points,
    )
    summary = {
        "object": problem.object.name,
        **perception.summary(),
        "true_pose": [float(x) for x in problem.object.pose],
    }
    write_atomic(paths["summary"], json.dumps(summary, indent=2) + "\n")
    write_atomic(paths["scene"], perceived_toml(problem, perception))
    return paths
