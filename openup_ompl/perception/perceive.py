"""One perception step: view -> noisy cloud -> superquadric fit -> object pose and ``u``.

The outputs of ``openup-ompl perceive`` are written here too: the cloud (NPZ), a summary
(``perception.json``) and ``perceived.toml``, the scene with the object at the estimate
and ``[hand] u`` from :func:`~openup_ompl.perception.uncertainty.u_from_covariance`.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable
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
    PerceptionError,
)
from openup_ompl.perception.camera import (
    CameraOptions,
    DepthCamera,
    DepthView,
    camera_of_scene,
)
from openup_ompl.perception.covariance import Outline, SuperquadricFit
from openup_ompl.perception.estimate import estimate, estimated_pose
from openup_ompl.perception.extrinsic import (
    CameraError,
    PerceptionOptions,
    draw_camera_error,
    extrinsic_covariance,
)
from openup_ompl.perception.fit import FitOptions, Silhouette, fit_superquadric
from openup_ompl.perception.noise import (
    NoiseOptions,
    PointCloud,
    kinect_sigmas,
    noise_covariance,
    noisy_cloud,
    normal_sigma,
)
from openup_ompl.perception.nominal import nominal_of
from openup_ompl.perception.superquadric import SOLIDS
from openup_ompl.perception.uncertainty import u_from_covariance
from openup_ompl.perception.view import checked_view, occluded_outline, silhouette_of
from openup_ompl.scene import Problem

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
            the scene shape's own frame (:func:`~openup_ompl.perception.estimate.estimated_pose`).
        u: The hand law's ``u`` from the covariance.
        camera: Camera position [m].
        target: The point [m] it looked at.
        pose_covariance: ``(6, 6)`` covariance of the estimate's position [m] and a small
            world-frame rotation [rad]: the fit's (a mesh's registration's) plus the
            camera's calibration errors' (:mod:`~openup_ompl.perception.extrinsic`), with
            no variance about a symmetry axis of the shape.
        camera_error: The view's calibration errors (drawn; the truth, for studies).
        u_fits: ``u`` of each fit of the view (the points, then bootstrap resamples of
            them: ``PerceptionOptions.restarts``); ``u`` is their median.
    """

    cloud: PointCloud
    fit: SuperquadricFit
    pose: np.ndarray
    u: float
    camera: np.ndarray
    target: np.ndarray
    pose_covariance: np.ndarray
    camera_error: CameraError
    u_fits: tuple[float, ...] = ()

    @property
    def u_spread(self) -> float:
        """Max minus min of :attr:`u_fits` (0 for one fit)."""
        return float(max(self.u_fits) - min(self.u_fits)) if self.u_fits else 0.0

    @property
    def position_covariance(self) -> np.ndarray:
        """``(3, 3)`` covariance [m^2] of the estimated position, world frame."""
        return self.pose_covariance[:3, :3].copy()

    @property
    def rotation_covariance(self) -> np.ndarray:
        """``(3, 3)`` covariance [rad^2] of a small world-frame rotation of the estimate."""
        return self.pose_covariance[3:, 3:].copy()

    def summary(self) -> dict[str, Any]:
        """The estimate as plain JSON-ready values.

        Returns:
            The pose, ``u`` and its fits, the fit's points, superquadric and residuals,
            the covariances, the camera and its calibration errors (SI units: m, rad).
        """
        sq = self.fit.superquadric
        return {
            "pose": [float(x) for x in self.pose],
            "u": self.u,
            "u_fits": list(self.u_fits),
            "u_spread": self.u_spread,
            "points": self.fit.points,
            "dropped": self.cloud.dropped,
            "sizes": sq.sizes.tolist(),
            "exponents": sq.exponents.tolist(),
            "diameter": self.fit.diameter,
            "mean_residual": self.fit.mean_residual,
            "residual_rms": self.fit.residual_rms,
            "position_covariance": self.position_covariance.tolist(),
            "rotation_covariance": self.rotation_covariance.tolist(),
            "pose_covariance": self.pose_covariance.tolist(),
            "camera": self.camera.tolist(),
            "target": self.target.tolist(),
            "camera_error": {
                "position": self.camera_error.position.tolist(),
                "rotation": self.camera_error.rotation.tolist(),
                "depth_bias": self.camera_error.depth_bias,
            },
        }


#: A fitted half-size within this factor of ``FitOptions.min_size`` is a collapsed fit
#: (:class:`DegenerateFit`): a fit collapsed onto the top a steep view sees ends at the
#: bound itself, and the closed loops' views fit half-sizes several times larger.
DEGENERATE_FACTOR = 1.5


def perceive(
    problem: Problem,
    camera: CameraOptions | str | None = None,
    noise: NoiseOptions | None = None,
    fit: FitOptions | None = None,
    *,
    rng: np.random.Generator | None = None,
    depth_camera: DepthCamera | None = None,
    silhouette: bool = True,
    weighted: bool = True,
    options: PerceptionOptions | None = None,
) -> Perception:
    """Look at the scene's object once, fit it, and choose ``u``.

    Args:
        problem: The scene; its object is where it truly is.
        camera: Camera options (ignored if ``depth_camera`` is given); ``None``: the
            scene file's ``[camera]`` table
            (:func:`~openup_ompl.perception.camera.camera_of_scene`); ``"auto"``: that
            view if it sees the object whole, else the best of a ring of views around it,
            as ``openup-ompl perceive`` does by default
            (:func:`~openup_ompl.perception.viewpoint.choose_camera`; ``NoViewSeesObject``
            when none does).
        noise: Sensor noise model.
        fit: Superquadric fit options.
        rng: The noise's random generator (default: seed 0).
        depth_camera: An already built camera (many views of one scene).
        silhouette: Use the view's free space in the fit
            (:class:`~openup_ompl.perception.fit.Silhouette`), and the surface under the
            object as its floor (it stands on the table, not through it).
        weighted: Weight the fit by the sensor's noise model (:func:`normal_sigma`); a
            mesh's registration also takes each point's distance less its expected excess
            under that noise (:func:`~openup_ompl.perception.noise.noise_covariance`).
        options: The camera's calibration errors (drawn from ``rng`` after the sensor
            noise, applied to the cloud and added to the covariance) and the estimator's
            bootstrap refits (their spread of ``u`` is reported; drawn from ``rng`` last);
            ``PerceptionOptions.exact()``: the sensor noise alone.

    Returns:
        The estimate: the object's pose, its covariance, the fit, the cloud and ``u``.

    Raises:
        ConfigError: ``depth_camera`` was built on another object (or pose) than the
            problem's.
        ObjectNotVisible: No point of the object is measured.
        TooFewPoints: Too few for the fit.
        ObjectCutOff: The object's pixels reach the image border (the view does not
            bound it).
        ObjectOccluded: More than :data:`~openup_ompl.perception.view.HIDDEN_SHARE` of
            the object's outline on one image side lies next to a nearer surface
            (:func:`~openup_ompl.perception.view.occluded_outline`), and nothing else
            bounds it there (the bottom of an object standing on a surface the rays find
            does not count).
        DegenerateFit: The fit collapsed onto one face (a half-size within
            :data:`DEGENERATE_FACTOR` of its lower bound).
    """
    noise = noise or NoiseOptions()
    options = options or PerceptionOptions()
    rng = rng if rng is not None else np.random.default_rng(0)
    cam = _camera(problem, camera, depth_camera)
    view = cam.render()
    cloud = noisy_cloud(view, noise, rng)
    error = draw_camera_error(options, rng)
    support = checked_view(problem, cam, view, cloud, noise, silhouette)
    cloud, view, support = _as_believed(cloud, view, error, support)
    shape = silhouette_of(view, noise, cam.options, support) if silhouette else None
    weights = normal_sigma(view.position, view.rotation, noise) if weighted else None
    spread = noise_covariance(view.position, view.rotation, noise) if weighted else None
    depth = np.median((cloud.points - view.position) @ view.rotation[:, 2], keepdims=True)
    lateral = float(kinect_sigmas(depth, np.zeros(1), noise)[1][0])
    focal = cam.options.intrinsics()[0]
    outline = Outline(cloud.points, view.position, focal, lateral, noise.max_incidence)
    sensor = (weights, spread)
    first = _fitted(problem, cloud.points, fit, shape, sensor, support, view, options, outline)
    result, pose, covariance, u = first
    fits = [u]
    for _ in range(options.restarts - 1):
        # A bootstrap resample of the points: the spread of u is the fit's own instability.
        sample = cloud.points[rng.integers(0, cloud.points.shape[0], cloud.points.shape[0])]
        try:
            again = _fitted(problem, sample, fit, shape, sensor, support, view, options, outline)
            fits.append(again[3])
        except PerceptionError:
            continue  # a resample that collapses says nothing of the view's u
    return Perception(
        cloud,
        result,
        pose,
        float(np.median(fits)),
        view.position.copy(),
        cam.target.copy(),
        covariance,
        error,
        tuple(fits),
    )


def _fitted(
    problem: Problem,
    points: np.ndarray,
    fit: FitOptions | None,
    shape: Silhouette | None,
    sensor: tuple[Callable[..., np.ndarray] | None, Callable[..., np.ndarray] | None],
    support: float | None,
    view: DepthView,
    options: PerceptionOptions,
    outline: Outline,
) -> tuple[SuperquadricFit, np.ndarray, np.ndarray, float]:
    """One fit of ``points`` (``sensor``: the noise's sigma along a normal and its
    covariance, or None): the superquadric, the object's pose, its ``(6, 6)`` covariance
    (the fit's with the view's ``outline``, the calibration errors', no turn about a
    symmetry axis) and ``u``."""
    assert problem.object is not None
    ties = {"cylinder": ((0, 1),), "sphere": ((0, 1), (1, 2))}.get(problem.object.shape, ())
    half = nominal_of(problem.object).half
    prior = (half, options.size_sigma, ties) if options.size_sigma else None
    solid = problem.object.shape if problem.object.shape in SOLIDS else None
    weights, spread = sensor
    result = fit_superquadric(points, fit, shape, weights, prior, solid)
    bound = (fit or FitOptions()).min_size
    if float(np.min(result.superquadric.sizes)) <= DEGENERATE_FACTOR * bound:
        raise DegenerateFit(result.superquadric.sizes.tolist(), bound)
    assert problem.object is not None
    outline = dataclasses.replace(outline, points=points)
    pose, covariance = estimate(
        result, problem.object, points, weights, support, options.size_sigma, outline, spread
    )
    covariance = covariance + extrinsic_covariance(options, view.position, view.rotation, pose[:3])
    rotation = pin.XYZQUATToSE3(pose).rotation
    covariance = without_turns(covariance, nominal_of(problem.object).symmetry_axes(rotation))
    u = u_from_covariance(
        covariance[:3, :3],
        covariance[3:, 3:],
        at_estimate(problem, pose),
        cross_covariance=covariance[:3, 3:],
    )
    return result, pose, covariance, u


def _as_believed(
    cloud: PointCloud, view: DepthView, error: CameraError, support: float | None
) -> tuple[PointCloud, DepthView, float | None]:
    """The cloud, the view's camera pose and the support's height as the robot has them:
    placed by the camera's believed pose, depths offset by the bias (:class:`CameraError`)."""
    position, rotation = view.position, view.rotation
    believed = dataclasses.replace(
        cloud,
        points=error.apply(cloud.points, position, rotation),
        scene_points=error.apply(cloud.scene_points, position, rotation),
    )
    if support is not None:
        foot = np.append(cloud.points[:, :2].mean(axis=0), support)
        support = error.move_height(foot, position, rotation)
    camera, turned = error.believed(position, rotation)
    return believed, dataclasses.replace(view, position=camera, rotation=turned), support


def without_turns(covariance: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """A pose covariance with no rotation about some world axes: a turn about a symmetry
    axis of the shape moves none of its surface.

    Args:
        covariance: Position [m] and small world-frame rotation [rad], shape ``(6, 6)``.
        axes: Unit world axes as rows, shape ``(k, 3)``.

    Returns:
        The projected covariance, shape ``(6, 6)`` (``covariance`` itself if ``k = 0``).
    """
    if axes.size == 0:
        return covariance
    keep = np.eye(6)
    keep[3:, 3:] -= axes.T @ axes
    return np.asarray(keep @ covariance @ keep.T)


def _camera(
    problem: Problem, camera: CameraOptions | str | None, depth_camera: DepthCamera | None
) -> DepthCamera:
    """The camera to look with: ``depth_camera`` (built on this problem's object), else one
    of ``camera`` (None: the scene file's; ``"auto"``: the scene file's if it sees the
    object whole, else the best of a ring,
    :func:`~openup_ompl.perception.viewpoint.choose_camera`)."""
    if depth_camera is None and camera == "auto":
        from openup_ompl.perception.viewpoint import choose_camera

        return choose_camera(problem, camera_of_scene(problem)).camera
    if isinstance(camera, str):
        raise ConfigError("camera", camera, "CameraOptions, None or 'auto'")
    if depth_camera is None:
        return DepthCamera(problem, camera or camera_of_scene(problem))
    if not _same_object(depth_camera.problem, problem):
        # Its scene is its own: it would measure that scene's object, reported as this one.
        theirs, ours = (getattr(q.object, "name", None) for q in (depth_camera.problem, problem))
        raise ConfigError(
            "depth_camera",
            f"a camera on {theirs!r}",
            f"a DepthCamera built on this problem's object ({ours!r}, at the same pose)",
        )
    return depth_camera


def _same_object(a: Problem, b: Problem) -> bool:
    """Whether two problems hold the same object at the same pose (the camera's scene)."""
    if a is b:
        return True
    if a.object is None or b.object is None:
        return a.object is b.object
    return a.object.to_table() == b.object.to_table()


def at_estimate(problem: Problem, pose: np.ndarray) -> Problem:
    """The problem as perception reports it: the object at ``pose`` and the grasp pose
    carried along (``T_grasp' = T_estimate T_nominal^-1 T_grasp``).

    Args:
        problem: The scene as loaded.
        pose: The object's estimated pose ``[x, y, z, qx, qy, qz, qw]`` [m, unit
            quaternion], world frame.

    Returns:
        A copy of ``problem`` with the object and the grasp pose moved.

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
    ``[hand] u`` set; a robot or a mesh file named by a relative path is written as an
    absolute one, so that the file plans from any directory.

    Args:
        problem: The scene as loaded from its file.
        perception: The estimate.

    Returns:
        The new scene file's text (TOML), with a header comment on the estimate.

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
    base = problem.path.parent
    for table in [raw["object"], *raw.get("obstacles", [])]:
        if isinstance(table, dict) and "file" in table:  # a mesh's file, read from anywhere
            table["file"] = str((base / str(table["file"])).resolve())
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
    ``out`` (created if missing).

    Args:
        problem: The scene as loaded from its file (the object at its true pose).
        perception: The estimate.
        out: The output directory.

    Returns:
        The paths written, by key: ``cloud``, ``summary``, ``scene``.

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
