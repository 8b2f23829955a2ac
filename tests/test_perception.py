"""Perception: the simulated camera, the Kinect noise model, the superquadric fit, its
covariance's calibration, the u rule and ``openup-ompl perceive``."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import openup_ompl as ou
from openup_ompl.exceptions import ConfigError, ObjectNotVisible, TooFewPoints
from openup_ompl.perception import (
    CameraOptions,
    DepthCamera,
    NoiseOptions,
    arrival_fraction,
    clearance_per_u,
    estimated_pose,
    fit_superquadric,
    kinect_sigmas,
    noisy_cloud,
    perceive,
    u_from_covariance,
)
from openup_ompl.perception._toml_writer import dumps
from openup_ompl.perception.extrinsic import PerceptionOptions
from openup_ompl.perception.figure import ELLIPSE_CHI2
from openup_ompl.scene import Shape

ROOT = Path(__file__).resolve().parent.parent
LWA3_SCENE = ROOT / "scenes" / "lwa3_sdh_can.toml"
#: The sensor noise alone: these tests are about the fit (the calibration errors
#: are tested in test_perception_errors.py).
EXACT = PerceptionOptions.exact()


@pytest.fixture(scope="module")
def lwa3_can() -> ou.Problem:
    return ou.load_scene(LWA3_SCENE)


@pytest.fixture(scope="module")
def lwa3_camera(lwa3_can: ou.Problem) -> DepthCamera:
    return DepthCamera(lwa3_can)


def _full_view_cloud(problem: ou.Problem) -> np.ndarray:
    """Noise-free points of the object from 12 cameras around it (every side seen)."""
    clouds = []
    for azimuth in (0, 90, 180, 270):
        for elevation in (-50, 0, 50):
            options = CameraOptions(azimuth=azimuth, elevation=elevation, distance=0.6)
            view = DepthCamera(problem, options).render()
            clouds.append(noisy_cloud(view, NoiseOptions(scale=0), np.random.default_rng(0)))
    points = np.concatenate([cloud.points for cloud in clouds])
    return points[::3]  # a third is plenty, and three times faster


def _floating(problem: ou.Problem, shape: Shape) -> ou.Problem:
    return dataclasses.replace(problem, obstacles=[], object=shape)


POSE = pin.SE3ToXYZQUAT(pin.SE3(pin.rpy.rpyToMatrix(0.3, -0.2, 0.7), np.array([0.6, 0.05, 0.3])))


@pytest.mark.parametrize(
    "shape",
    [
        Shape("box", "box", np.array(POSE), size=np.array([0.05, 0.08, 0.12])),
        Shape("can", "cylinder", np.array(POSE), radius=0.03, length=0.12),
    ],
    ids=["box", "cylinder"],
)
def test_noise_free_full_view_recovers_pose_and_size(lwa3_can: ou.Problem, shape: Shape) -> None:
    """A noise-free view of every side gives the pose within 1 mm and 1 deg, sizes 2 %."""
    fit = fit_superquadric(_full_view_cloud(_floating(lwa3_can, shape)))
    pose = estimated_pose(fit, shape)
    assert np.linalg.norm(pose[:3] - shape.pose[:3]) < 1e-3
    truth = pin.XYZQUATToSE3(shape.pose).rotation
    # estimated_pose picks, among the superquadric's symmetric frames, the one nearest the
    # nominal: for a box the angle is the true error; for a cylinder compare the axis only.
    estimate = pin.XYZQUATToSE3(pose).rotation
    if shape.shape == "box":
        angle = np.linalg.norm(pin.log3(truth.T @ estimate))
        sizes = np.sort(2 * fit.superquadric.sizes)
        expected = np.sort(shape.size)
    else:
        angle = math.acos(min(1.0, abs(float(truth[:, 2] @ estimate[:, 2]))))
        a1, a2, a3 = fit.superquadric.sizes
        sizes, expected = np.array([a1, a2, 2 * a3]), np.array([0.03, 0.03, 0.12])
    assert math.degrees(angle) < 1.0
    assert np.all(np.abs(sizes / expected - 1) < 0.02)


@pytest.mark.parametrize("column", [0, 1, 2])
def test_a_cylinder_is_read_along_the_superquadric_axis_that_fits_it(column: int) -> None:
    """An upright can fitted by a superquadric whose long axis is its x, y or z (the fit
    starts from every principal axis) is estimated upright: its axis is read from the
    half-sizes, not from the superquadric's z (which laid the Panda's can on its side in
    10 of 20 noisy views, and its grasp pose with it)."""
    from openup_ompl.perception.covariance import SuperquadricFit
    from openup_ompl.perception.superquadric import N_PARAMETERS, Superquadric

    nominal = Shape("can", "cylinder", np.array([0.6, 0.0, 0.06, 0, 0, 0, 1.0]), radius=0.03,
                    length=0.12)  # fmt: skip
    tilted = pin.rpy.rpyToMatrix(0.05, -0.03, 0.4)  # the can's true frame, 3 deg off upright
    sizes = np.array([0.028, 0.031, 0.029])
    sizes[column] = 0.058
    # The superquadric's frame: the can's axis (tilted z) as its column `column`.
    order = [(column + 1 + k) % 3 for k in range(3)]
    rotation = tilted[:, np.argsort(order)]
    assert np.allclose(rotation[:, column], tilted[:, 2]) and np.linalg.det(rotation) > 0
    fit = SuperquadricFit(
        Superquadric(sizes, np.array([0.1, 1.0]), np.array([0.6, 0.0, 0.06]), rotation),
        np.eye(N_PARAMETERS), 0.001, 0.001, 300, 50,
    )  # fmt: skip
    axis = pin.XYZQUATToSE3(estimated_pose(fit, nominal)).rotation[:, 2]
    assert axis @ tilted[:, 2] == pytest.approx(1.0)


def test_kinect_noise_model_values() -> None:
    """Nguyen et al. 2012 at 1 m, face-on: 1.884 mm axial, 0.8 px of 585 px lateral."""
    axial, lateral = kinect_sigmas(np.array([1.0]), np.array([0.0]))
    assert axial[0] == pytest.approx(0.0012 + 0.0019 * 0.36)
    assert lateral[0] == pytest.approx(0.8 / 585)
    grazing, _ = kinect_sigmas(np.array([1.0]), np.array([math.radians(60)]))
    assert grazing[0] > axial[0]
    doubled, _ = kinect_sigmas(np.array([1.0]), np.array([0.0]), NoiseOptions(scale=2.0))
    assert doubled[0] == pytest.approx(2 * axial[0])


def test_grazing_points_drop_out(lwa3_camera: DepthCamera) -> None:
    """No kept point meets its surface beyond max_incidence; the object loses some."""
    view = lwa3_camera.render()
    cloud = noisy_cloud(view, NoiseOptions(max_incidence=60.0), np.random.default_rng(1))
    assert cloud.dropped > 0
    assert np.all(view.incidence[cloud.pixels] <= math.radians(60.0))
    assert np.all(np.isin(view.geom[cloud.pixels], view.object_geoms))


@pytest.mark.slow
def test_covariance_is_calibrated(lwa3_can: ou.Problem, lwa3_camera: DepthCamera) -> None:
    """Over 200 noisy views the true centre is inside the fit's 2-sigma ellipse (world x-y,
    95.45 %: chi^2_2 = 6.18) in 85-99 % of views; with the covariance scaled by 0.25, not.

    The ellipse is the 2D region with the probability of +-2 sigma in one dimension, so a
    calibrated covariance expects 95 % (a binomial sd of 1.5 % over 200 views); a radius-2
    ellipse would expect 86.5 %, too close to the lower bound to tell calibration apart.
    """
    rng = np.random.default_rng(2026)
    truth = lwa3_can.object.pose[:2]  # type: ignore[union-attr]
    d2 = []
    for _ in range(200):
        perception = perceive(lwa3_can, depth_camera=lwa3_camera, rng=rng, options=EXACT)
        error = perception.fit.superquadric.position[:2] - truth
        covariance = perception.fit.position_covariance[:2, :2]
        d2.append(float(error @ np.linalg.solve(covariance, error)))
    inside = np.mean(np.array(d2) <= ELLIPSE_CHI2)
    assert 0.85 <= inside <= 0.99
    shrunk = np.mean(np.array(d2) / 0.25 <= ELLIPSE_CHI2)
    assert not 0.85 <= shrunk <= 0.99


def test_u_grows_with_noise(lwa3_can: ou.Problem, lwa3_camera: DepthCamera) -> None:
    """The mean u over a few views grows with the sensor's noise scale."""
    means = []
    for scale in (0.5, 1.0, 2.0, 4.0):
        rng = np.random.default_rng(7)
        us = [
            perceive(
                lwa3_can,
                noise=NoiseOptions(scale=scale),
                depth_camera=lwa3_camera,
                rng=rng,
                options=EXACT,
            ).u
            for _ in range(4)
        ]
        means.append(float(np.mean(us)))
    assert all(0.0 <= u <= 1.0 for u in means)
    assert np.all(np.diff(means) > 0), means


def test_clearance_per_u_from_the_robot_geometry(lwa3_can: ou.Problem) -> None:
    """Panda: each finger travels 3 mm more at u = 1 in the demo scene (b 0.037, w 0.04);
    the paper's three-finger hand gains centimetres."""
    panda = ou.load_scene(ou.default_scene_path())
    assert clearance_per_u(panda) == pytest.approx(0.003, abs=1e-6)
    assert 0.01 < clearance_per_u(lwa3_can) < 0.1


def test_arrival_fraction_is_the_law_s_opening_left_at_the_object(lwa3_can: ou.Problem) -> None:
    """The share of the extra opening left when the fingertips reach the object shrinks by
    delta / (D0 mga) when the object moves delta away along the approach; 1 for a law that
    arrives open; the arrival-aware u divides the clearance by it."""
    import dataclasses

    share = arrival_fraction(lwa3_can)
    assert 0.0 < share < 1.0
    law = lwa3_can.hand_law
    grasp = lwa3_can.grasp
    approach = grasp.rotation @ np.asarray(lwa3_can.robot.spec.approach, dtype=float)
    assert lwa3_can.object is not None
    pose = np.array(lwa3_can.object.pose, dtype=float)
    pose[:3] += 0.005 * approach / np.linalg.norm(approach)
    moved = dataclasses.replace(lwa3_can, object=dataclasses.replace(lwa3_can.object, pose=pose))
    robot = lwa3_can.robot
    start = robot.palm_placement(robot.model.createData(), robot.full_q(lwa3_can.start, law(1.0)))
    d0 = float(np.linalg.norm(start.translation - grasp.translation))
    assert law.distance == "translation"  # D0 is the palm's distance alone
    assert arrival_fraction(moved) == pytest.approx(share - 0.005 / (d0 * law.mga), abs=1e-9)
    opened = dataclasses.replace(lwa3_can, hand_law=law.with_options(open_arrival=True))
    assert arrival_fraction(opened) == 1.0
    covariance = np.eye(3) * 0.002**2
    plain = u_from_covariance(covariance, np.zeros((3, 3)), lwa3_can)
    assert 0.0 < plain < share  # small enough that neither is clipped at 1
    at_arrival = u_from_covariance(covariance, np.zeros((3, 3)), lwa3_can, at_arrival=True)
    assert at_arrival == pytest.approx(plain / share)
    with pytest.raises(ConfigError, match="at_arrival"):
        u_from_covariance(covariance, np.zeros((3, 3)), lwa3_can, at_arrival="yes")  # type: ignore[arg-type]


def test_camera_looking_away_sees_no_object(lwa3_can: ou.Problem) -> None:
    """A camera turned away from the object raises ObjectNotVisible naming it."""
    options = CameraOptions(position=(0.75, -0.2, 0.5), target=(0.75, -0.2, 1.5))
    with pytest.raises(ObjectNotVisible, match="can"):
        perceive(lwa3_can, options, options=EXACT)


@pytest.mark.parametrize(
    ("options", "named"),
    [
        (CameraOptions(distance=0.01), "camera.distance"),
        (CameraOptions(position=(0.75, -0.2, 0.1)), "camera.position"),
    ],
)
def test_camera_inside_the_object_is_refused(
    lwa3_can: ou.Problem, options: CameraOptions, named: str
) -> None:
    """A camera within the object's bounding sphere is a ConfigError naming its place (it
    saw the object from within: a 130 mm error reported as a fit)."""
    with pytest.raises(ConfigError, match=named):
        perceive(lwa3_can, options, options=EXACT)


def test_too_few_points(lwa3_can: ou.Problem) -> None:
    """A tiny image, or a handful of points, raises TooFewPoints with the count."""
    with pytest.raises(TooFewPoints) as error:
        perceive(lwa3_can, CameraOptions(width=24, height=18), options=EXACT)
    assert error.value.points < error.value.needed
    with pytest.raises(TooFewPoints):
        fit_superquadric(np.zeros((5, 3)))


@pytest.mark.parametrize("points", [np.zeros((100, 2)), np.zeros(100), np.zeros((4, 25, 3))])
def test_cloud_of_another_shape_is_named_by_its_shape(points: np.ndarray) -> None:
    """Rows that are not [x, y, z] are a ConfigError giving the shape (it was
    TooFewPoints: '100 points, expected at least 22')."""
    with pytest.raises(ConfigError, match=r"points: got 'an array of shape \("):
        fit_superquadric(points)


@pytest.mark.parametrize(
    "points",
    [np.zeros((50, 3)), np.outer(np.linspace(0.0, 0.1, 50), [1.0, 0.5, 0.0])],
    ids=["one place", "a line"],
)
def test_degenerate_cloud_is_refused(points: np.ndarray) -> None:
    """Points at one place or on a line fit perfectly, with a zero covariance (u = 0 from
    no information): refused, naming the points."""
    with pytest.raises(ConfigError, match="points"):
        fit_superquadric(points)


@pytest.mark.parametrize(
    "covariance",
    [
        -np.eye(3),
        np.full((3, 3), np.nan),
        np.eye(2),
        np.array([[1.0, 0.5, 0], [0, 1, 0], [0, 0, 1]]),
    ],
    ids=["negative", "nan", "2 x 2", "asymmetric"],
)
def test_u_from_a_covariance_that_is_not_one_is_refused(
    lwa3_can: ou.Problem, covariance: np.ndarray
) -> None:
    """A position covariance that is not a 3 x 3 positive semi-definite matrix is a
    ConfigError (a negative one gave u = 0)."""
    with pytest.raises(ConfigError, match="position_covariance"):
        u_from_covariance(covariance, np.eye(3) * 1e-4, lwa3_can)


@pytest.mark.parametrize("key", ["fx", "fy", "cx", "fov"])
def test_nan_intrinsics_name_the_value(key: str) -> None:
    """NaN intrinsics raise ConfigError naming the key."""
    with pytest.raises(ConfigError, match=f"camera.{key}"):
        CameraOptions(**{key: float("nan")})


def test_toml_writer_round_trips() -> None:
    """The scene writer's output reads back as the same document."""
    import tomllib

    document = {
        "robot": "panda",
        "start": [0.0, -0.5],
        "hand": {"u": 0.25, "continuous": True},
        "object": {"name": "can", "pose": [0.6, 0.0, 0.06, 0.0, 0.0, 0.0, 1.0]},
        "obstacles": [{"name": "a", "size": [1, 2, 3]}, {"name": "b", "radius": 0.1}],
    }
    assert tomllib.loads(dumps(document)) == document


def test_perceive_cli_writes_a_plannable_scene(tmp_path: Path) -> None:
    """perceive writes the cloud and perceived.toml (robot path made absolute, object at
    the estimate, u from the covariance) that plan accepts."""
    from openup_ompl.__main__ import main

    scene = tmp_path / "scenes" / "can.toml"
    scene.parent.mkdir()
    text = LWA3_SCENE.read_text().replace('robot = "lwa3_sdh"', 'robot = "../robots/lwa3_sdh.toml"')
    scene.write_text(text + "\n[camera]\ndistance = 0.9\n")
    (tmp_path / "robots").symlink_to(ROOT / "robots")
    out = tmp_path / "out"
    exact = ["--camera-position-sigma", "0", "--camera-angle-sigma", "0", "--depth-bias-sigma", "0"]
    assert main(["perceive", str(scene), "--seed", "3", "--out", str(out), *exact]) == 0
    assert (out / "cloud.npz").is_file()
    assert json.loads((out / "perception.json").read_text())["object"] == "can"
    perceived = out / "perceived.toml"
    problem = ou.load_scene(perceived)
    truth = ou.load_scene(scene)
    assert problem.object is not None and truth.object is not None
    assert np.linalg.norm(problem.object.pose[:3] - truth.object.pose[:3]) < 0.01
    assert 0.0 <= problem.hand_law.u <= 1.0
    assert main(["plan", str(perceived), "--time", "10", "--seed", "1"]) == 0


def test_perceive_cli_bad_camera_key_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """An unknown --camera key ends with one line naming it and exit status 2."""
    from openup_ompl.__main__ import main

    status = main(["perceive", str(LWA3_SCENE), "--camera", "zoom=2", "--out", str(tmp_path)])
    assert status == 2
    assert "camera.zoom" in capsys.readouterr().err


def test_at_estimate_carries_the_grasp_with_the_object(lwa3_can: ou.Problem) -> None:
    """Planning at the estimate moves the grasp pose rigidly with the object."""
    from openup_ompl.perception import at_estimate

    assert lwa3_can.object is not None
    pose = lwa3_can.object.pose.copy()
    pose[:2] += [0.01, -0.02]
    moved = at_estimate(lwa3_can, pose)
    assert np.allclose(moved.grasp_pose[:2] - lwa3_can.grasp_pose[:2], [0.01, -0.02])
    assert np.allclose(moved.grasp_pose[2:], lwa3_can.grasp_pose[2:])


def test_closed_loop_takes_the_judge_as_an_argument(lwa3_can: ou.Problem) -> None:
    """Each policy of a trial is planned at the same estimate and judged against the
    truth by the judge given; the summary has the contract's columns."""
    from openup_ompl.perception.closed_loop import (
        CSV_COLUMNS,
        ClosedLoopOptions,
        closed_loop,
        summarize,
    )

    seen: list[tuple[float, np.ndarray]] = []

    def judge(setup, plan, truth):  # type: ignore[no-untyped-def]
        assert truth is lwa3_can
        seen.append((setup.law.u, setup.problem.object.pose))
        return {"success": setup.law.u > 0.5}

    options = ClosedLoopOptions(
        policies=("0", "1", "covariance"),
        noises=(1.0,),
        distances=(0.8,),
        trials=1,
        perception=EXACT,
    )
    rows = summarize(closed_loop(lwa3_can, options, judge=judge))
    assert len(seen) == 3 and all(np.allclose(pose, seen[0][1]) for _, pose in seen)
    assert {row["policy"]: row["successes"] for row in rows} == {"0": 0, "1": 1, "covariance": 0}
    assert set(CSV_COLUMNS[:6]) <= set(rows[0])


def test_write_perception_takes_a_str_and_refuses_a_file(lwa3_can, lwa3_camera, tmp_path):
    """``write_perception`` writes its three files into a directory given as a string,
    the perceived scene loading back with the fitted pose; a path that is a file, or a
    problem without an object, is refused before anything is written."""
    from openup_ompl.perception import write_perception

    perception = perceive(
        lwa3_can, depth_camera=lwa3_camera, rng=np.random.default_rng(3), options=EXACT
    )
    paths = write_perception(lwa3_can, perception, str(tmp_path / "out"))
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [
        "cloud.npz",
        "perceived.toml",
        "perception.json",
    ]
    perceived = ou.load_scene(paths["scene"])
    assert perceived.object is not None
    assert not np.allclose(perceived.object.pose, lwa3_can.object.pose)  # type: ignore[union-attr]
    (tmp_path / "afile").write_text("")
    with pytest.raises(ConfigError, match="afile"):
        write_perception(lwa3_can, perception, tmp_path / "afile")
    bare = dataclasses.replace(lwa3_can, object=None)
    with pytest.raises(ou.InvalidProblem, match="no \\[object\\]"):
        write_perception(bare, perception, tmp_path / "bare")
    in_code = dataclasses.replace(lwa3_can, path=None)
    with pytest.raises(ou.InvalidProblem, match="not loaded from a scene file"):
        write_perception(in_code, perception, tmp_path / "bare")
    assert not (tmp_path / "bare").exists()


def test_perceive_reads_the_scene_camera_as_the_command_does():
    """``perceive(problem)`` looks through the scene file's ``[camera]`` (the Panda's
    can scene sets one: at the default camera the can showed too few points), and
    ``at_estimate`` refuses a pose the plan file would refuse later."""
    from openup_ompl.perception.camera import camera_of_scene
    from openup_ompl.perception.cli import scene_camera
    from openup_ompl.perception.perceive import at_estimate

    problem = ou.load_scene(ROOT / "scenes" / "panda_can.toml")
    assert camera_of_scene(problem) == scene_camera(problem, []) != CameraOptions()
    perception = perceive(problem, options=EXACT)
    assert 0.0 <= perception.u <= 1.0
    moved = at_estimate(problem, perception.pose)
    assert moved.object is not None and moved.grasp_pose.shape == (7,)
    for pose in ([0.6, 0.0, 0.2, 0.0, 0.0, 0.0, 2.0], [math.nan] * 7, [0.0] * 3):
        with pytest.raises(ConfigError, match="^pose"):
            at_estimate(problem, np.array(pose))


@pytest.mark.parametrize(
    ("changes", "named"),
    [
        ({"policies": ("0", "0.0")}, "policies"),
        ({"noises": (1.0, 1.0)}, "noises"),
        ({"distances": (0.6, 0.6)}, "distances"),
        ({"distances": (-1.0,)}, "camera.distance"),
        ({"camera": CameraOptions(position=(1.2, -0.2, 0.6))}, "distances"),
    ],
)
def test_closed_loop_sweep_refuses_values_it_would_count_twice(changes, named):
    """A policy, noise or distance given twice (the same views counted twice in one row),
    or several distances with a fixed camera position (every distance the same view)."""
    from openup_ompl.perception.closed_loop import ClosedLoopOptions

    with pytest.raises(ConfigError, match=f"^{named}"):
        ClosedLoopOptions(**changes)
    ClosedLoopOptions(camera=CameraOptions(position=(1.2, -0.2, 0.6)), distances=(0.8,))


def test_an_explicit_camera_position_excludes_an_orbit():
    """``position`` and ``distance``/``elevation``/``azimuth`` in one table is refused (the
    orbit was silently ignored); an override of either kind replaces the scene's other
    kind (the Panda scene's [camera] sets an elevation)."""
    from openup_ompl.perception.camera import CameraOptions, camera_of_scene

    with pytest.raises(ou.ConfigError, match="camera.distance"):
        CameraOptions.from_table({"position": [1.0, 0.0, 0.8], "distance": 1.0})
    problem = ou.load_scene(ou.default_scene_path())
    assert camera_of_scene(problem).elevation == 60.0
    placed = camera_of_scene(problem, {"position": [1.0, 0.0, 0.8]})
    assert placed.position == (1.0, 0.0, 0.8) and placed.elevation != 60.0
    orbit = camera_of_scene(problem, {"distance": 0.9})
    assert orbit.position is None and orbit.distance == 0.9 and orbit.elevation == 60.0


def test_a_fit_collapsed_onto_one_face_is_refused():
    """From 75 degrees above, the LWA3's can shows its top face. Without the scene's sizes
    the fit shrinks its height to the bound (the centre 79 mm too high with a 0.1 mm
    sigma): a DegenerateFit (a PerceptionError: the closed loop counts the view as not
    seen), naming the half-sizes. With them, held to a cylinder standing on the table in
    their order, it is within 3 mm (matched in any order, the collapsed height took the
    radius's 33 mm, 46 mm too high)."""
    from openup_ompl.exceptions import DegenerateFit, PerceptionError
    from openup_ompl.perception.camera import camera_of_scene

    problem = ou.load_scene(ou.default_scene_path().parent / "lwa3_sdh_can.toml")
    assert problem.object is not None
    steep = camera_of_scene(problem, {"elevation": 75.0, "distance": 0.8})
    legacy = PerceptionOptions.legacy()
    with pytest.raises(DegenerateFit, match="collapsed onto one face") as caught:
        perceive(problem, steep, rng=np.random.default_rng(1), options=legacy)
    assert isinstance(caught.value, PerceptionError)
    assert min(caught.value.sizes) <= 1.5 * caught.value.bound
    seen = perceive(problem, steep, rng=np.random.default_rng(1), options=EXACT)
    assert np.linalg.norm(seen.pose[:3] - problem.object.pose[:3]) < 0.003


def test_closed_loop_options_default_to_the_scene_camera():
    """``ClosedLoopOptions()`` looks with the scene file's ``[camera]``, as the command does:
    the Panda's can, hidden behind its wall from the built-in 40 degrees, is seen from the
    scene's 60; the same records as with that camera passed explicitly."""
    from openup_ompl.perception.camera import camera_of_scene
    from openup_ompl.perception.closed_loop import ClosedLoopOptions, closed_loop

    problem = ou.load_scene(ROOT / "scenes" / "panda_can.toml")
    sweep = {"policies": ("0.3",), "noises": (1.0,), "distances": (0.8,), "trials": 1}

    lines: list[str] = []

    def run(**camera: CameraOptions) -> list[dict]:
        options = ClosedLoopOptions(**sweep, **camera)
        return closed_loop(problem, options, judge=judged, progress=lines.append)

    def judged(setup, plan, truth):  # type: ignore[no-untyped-def]
        return {"success": True}

    default = run()
    assert [record["seen"] for record in default] == [True]
    assert default == run(camera=camera_of_scene(problem))
    assert [record["seen"] for record in run(camera=CameraOptions())] == [False]
    # Each view reports its end, a refused one too (it had printed nothing).
    assert len(lines) == 3 and "(not seen: TooFewPoints)" in lines[-1]


def test_support_under_the_object_is_the_table_it_stands_on():
    """A ray down through the object's points finds the table's top (z = 0); points held
    more than SUPPORT_GAP above it, or reaching below it, have no support."""
    from openup_ompl.perception.camera import SUPPORT_GAP

    camera = DepthCamera(ou.load_scene(ROOT / "scenes" / "panda_can.toml"))
    rng = np.random.default_rng(0)
    can = np.column_stack([0.6 + rng.uniform(-0.02, 0.02, (50, 2)), rng.uniform(0, 0.12, 50)])
    can[:, 1] -= 0.6
    assert camera.support_under(can + [0, 0, 0.02]) == pytest.approx(0.0, abs=1e-9)
    assert camera.support_under(can + [0, 0, SUPPORT_GAP + 0.01]) is None
    assert camera.support_under(can - [0, 0, 0.03]) is None


def test_a_view_from_above_keeps_the_can_on_the_table():
    """From the Panda scene's 60 degrees the can's base is hidden: without its support the
    fit floated it 10 mm above the table, or (seed 5) sank it 165 mm through it. Standing
    on the support it is within a few millimetres in height, and still in x, y."""
    from openup_ompl.perception.camera import camera_of_scene

    problem = ou.load_scene(ROOT / "scenes" / "panda_can.toml")
    camera = DepthCamera(problem, camera_of_scene(problem))
    for seed in (1, 5):
        seen = perceive(
            problem, depth_camera=camera, rng=np.random.default_rng(seed), options=EXACT
        )
        error = seen.pose[:3] - problem.object.pose[:3]
        assert abs(error[2]) < 0.003 and np.linalg.norm(error[:2]) < 0.005, (seed, error)


@pytest.mark.parametrize(
    ("camera", "sides"),
    [({"fx": 200.0, "cy": 120.0}, ["bottom"]), ({"distance": 0.12}, ["top", "bottom"])],
)
def test_an_object_running_off_the_image_is_refused(lwa3_can, camera, sides):
    """A view that cuts the can off at the image border does not bound it: the fit grew it
    past the border (49 mm too high, sigma 0.9 mm) and was written as an estimate."""
    from openup_ompl.exceptions import ObjectCutOff, PerceptionError

    with pytest.raises(ObjectCutOff, match=" and ".join(sides)) as refused:
        perceive(lwa3_can, CameraOptions(**camera), options=EXACT)
    assert isinstance(refused.value, PerceptionError) and refused.value.sides == sides
    assert refused.value.pixels > 0


def test_an_object_whose_outline_is_hidden_is_refused(lwa3_can):
    """The Panda's can seen over its scene's wall from 50 degrees: the wall hides the
    can's lower half, no support is found that far below its points, and the fit was a
    disc of its top, 45 mm too high with a 0.7 mm sigma, written as an estimate. From 60
    degrees the wall hides its base too, but the table found under it bounds it. A post
    in front of the LWA3's can hiding its left outline is refused as well (the view does
    not bound it there, whatever the fit makes of it)."""
    from openup_ompl.exceptions import ObjectOccluded, PerceptionError

    panda = ou.load_scene(ROOT / "scenes" / "panda_can.toml")
    camera = DepthCamera(panda, CameraOptions(elevation=50.0))
    # Every view, whatever its noise: a rule that let the fit's own extent behind the wall
    # bound it accepted views 37-43 mm off (noise 1 seed 7; noise 4 seeds 1, 4, 6, 8).
    for noise, seed in [(1.0, 3), (1.0, 7), (4.0, 1), (4.0, 4), (4.0, 6), (4.0, 8)]:
        with pytest.raises(ObjectOccluded, match="bottom side") as refused:
            perceive(
                panda,
                noise=NoiseOptions(scale=noise),
                depth_camera=camera,
                rng=np.random.default_rng(seed),
                options=EXACT,
            )
        assert isinstance(refused.value, PerceptionError) and refused.value.sides == ["bottom"]
    seen = perceive(
        panda, CameraOptions(elevation=60.0), rng=np.random.default_rng(3), options=EXACT
    )
    assert abs(seen.pose[2] - panda.object.pose[2]) < 0.003

    can = lwa3_can.object.pose[:3]
    camera = DepthCamera(lwa3_can)
    toward = (can - camera.position)[:2] / np.linalg.norm((can - camera.position)[:2])
    across = np.array([-toward[1], toward[0]])
    at = can[:2] - 0.12 * toward + 0.02 * across
    post = Shape("post", "box", np.array([*at, 0.2, 0, 0, 0, 1.0]), size=[0.02, 0.02, 0.4])
    hidden = dataclasses.replace(lwa3_can, obstacles=(*lwa3_can.obstacles, post))
    with pytest.raises(ObjectOccluded) as refused:
        perceive(hidden, rng=np.random.default_rng(1), options=EXACT)
    assert refused.value.sides == ["left"] and refused.value.pixels > 0


def test_the_closed_loop_defaults_are_the_commands():
    """``ClosedLoopOptions()`` sweeps what ``openup-ompl closed-loop`` sweeps (its noises
    were 0.5, 1, 2 against the command's 1, 2, 4, the README tables')."""
    from openup_ompl.__main__ import build_parser
    from openup_ompl.perception.closed_loop import ClosedLoopOptions

    args = build_parser().parse_args(["closed-loop", "--out", "x"])
    options = ClosedLoopOptions()
    assert tuple(args.noise) == options.noises
    assert tuple(args.distance) == options.distances
    assert tuple(args.policies) == options.policies
    assert args.trials == options.trials


def test_an_interrupted_closed_loop_writes_the_views_that_ended(tmp_path):
    """Ctrl-C during ``closed-loop`` (minutes long in physics) writes the table of the
    views that ended, for every policy, and exits 130 in one line, no traceback."""
    import csv
    import os
    import signal
    import subprocess
    import sys

    out = tmp_path / "out"
    command = [sys.executable, "-m", "openup_ompl", "closed-loop", "--trials", "50",
               "--noise", "1", "--distance", "0.6", "--out", str(out)]  # fmt: skip
    # Ctrl-C's default action restored in the child: a suite started in the background
    # by a non-interactive shell passes SIGINT on as ignored, and Python then keeps it so.
    process = subprocess.Popen(
        command,
        stderr=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
        cwd=tmp_path,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    assert process.stderr is not None
    ended = 0
    try:
        for line in process.stderr:
            ended += " done" in line
            if ended == 2:
                process.send_signal(signal.SIGINT)
                break
        stdout, stderr = process.communicate(timeout=120)
    finally:
        process.kill()  # a no-op once it has ended; never left running
    assert process.returncode == 130, stderr
    assert "Traceback" not in stderr and "interrupted" in stderr
    with (out / "closed_loop.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    trials = {int(row["trials"]) for row in rows}
    assert len(rows) == 4 and len(trials) == 1 and trials.pop() >= 2
    assert os.path.getsize(out / "closed_loop_trials.json") > 0


def test_a_camera_built_on_another_object_is_refused(lwa3_can, lwa3_camera):
    """A DepthCamera measures its own scene's object: handed a problem with another
    object (or the same one moved) it would report that object's fit as this one's."""
    DX = np.array([0.01, 0, 0, 0, 0, 0, 0])  # noqa: N806 - a constant of the test
    moved = dataclasses.replace(
        lwa3_can, object=dataclasses.replace(lwa3_can.object, pose=lwa3_can.object.pose + DX)
    )
    with pytest.raises(ConfigError, match="^depth_camera: got .a camera on 'can'"):
        perceive(moved, depth_camera=lwa3_camera, options=EXACT)
    assert perceive(lwa3_can, depth_camera=lwa3_camera, options=EXACT).fit.points > 0


def test_a_can_as_long_as_it_is_wide_is_read_upright():
    """A squat can (r 33 mm, 66 mm long) leaves the half-sizes no say about its axis: a
    box-like superquadric with its x vertical (half-sizes 33, 25, 31.6 mm) was read lying
    on its side. The scene's axis breaks the tie; a superquadric round about its z
    (e2 >= 0.5, flat ends) is read along its z."""
    from openup_ompl.perception.covariance import SuperquadricFit
    from openup_ompl.perception.superquadric import N_PARAMETERS, Superquadric

    nominal = Shape("can", "cylinder", np.array([0.75, -0.2, 0.033, 0, 0, 0, 1.0]), radius=0.033,
                    length=0.066)  # fmt: skip
    x_up = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])  # its x is world z
    for sizes, exponents, rotation in (
        ([0.033, 0.025, 0.0316], [0.09, 0.08], x_up),
        ([0.033, 0.034, 0.033], [0.1, 1.0], np.eye(3)),
    ):
        fit = SuperquadricFit(
            Superquadric(np.array(sizes), np.array(exponents), nominal.pose[:3], rotation),
            np.eye(N_PARAMETERS), 0.001, 0.001, 300, 50,
        )  # fmt: skip
        axis = pin.XYZQUATToSE3(estimated_pose(fit, nominal)).rotation[:, 2]
        assert abs(axis[2]) == pytest.approx(1.0), (sizes, axis)


@pytest.mark.parametrize("stand", ["held 3 cm up", "on a post"])
def test_no_support_is_assumed_under_an_object_that_does_not_stand_on_it(lwa3_can, stand):
    """Rays cast down through a can held 3 cm above the table (or standing on a thin post
    they miss) hit the table; the view sees space under it, so the fit is not pulled
    down onto the table (it was, 14 mm, with a 0.15 mm sigma)."""
    from openup_ompl.perception.camera import camera_of_scene, gap_under

    can = lwa3_can.object
    raised = dataclasses.replace(can, pose=can.pose + np.array([0, 0, 0.03, 0, 0, 0, 0]))
    obstacles = list(lwa3_can.obstacles)
    if stand == "on a post":
        x, y = can.pose[:2]
        post = [x, y, 0.015, 0, 0, 0, 1.0]
        obstacles.append(Shape("post", "cylinder", np.array(post), radius=0.008, length=0.03))
    problem = dataclasses.replace(lwa3_can, object=raised, obstacles=obstacles)
    camera = DepthCamera(problem, camera_of_scene(problem))
    assert gap_under(camera.render()) > 0.5 and gap_under(DepthCamera(lwa3_can).render()) < 0.5
    for seed in (1, 2):
        seen = perceive(
            problem, depth_camera=camera, rng=np.random.default_rng(seed), options=EXACT
        )
        assert abs(seen.fit.superquadric.position[2] - raised.pose[2]) < 0.005


def test_the_free_space_bounds_the_fit_but_is_not_counted_as_a_measurement(lwa3_can):
    """A thin stick (r 15, l 300 mm) where the can stands, at the Kinect's noise: the fits
    that grow away from the camera press a few surface samples past the silhouette's
    one-pixel band, and counted in ``J`` those samples made the covariance millimetres for
    centimetres of error (14 of 40 views outside the 2-sigma ellipse with them, 4 without).
    The covariance is the points' and the support's; the silhouette still shapes the fit."""
    x, y = lwa3_can.object.pose[:2]
    pose = np.array([x, y, 0.15, 0, 0, 0, 1.0])
    stick = Shape("stick", "cylinder", pose, radius=0.015, length=0.3)
    problem = dataclasses.replace(lwa3_can, object=stick)
    camera = DepthCamera(problem)
    outside = 0
    for seed in range(2026, 2066):
        seen = perceive(
            problem, depth_camera=camera, rng=np.random.default_rng(seed), options=EXACT
        )
        error = seen.fit.superquadric.position[:2] - stick.pose[:2]
        covariance = seen.fit.position_covariance[:2, :2]
        outside += float(error @ np.linalg.solve(covariance, error)) > ELLIPSE_CHI2
    assert outside <= 8, outside
