"""Perception of mesh objects: the shape's symmetry read from its hull, the hull registered
onto the cloud, and ``openup-ompl perceive`` on the shipped bottle scene."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import openup_ompl as ou
from openup_ompl.__main__ import main
from openup_ompl.perception import NoiseOptions, perceive
from openup_ompl.perception.extrinsic import PerceptionOptions
from openup_ompl.perception.nominal import nominal_of

ROOT = Path(__file__).resolve().parent.parent
BOTTLE_SCENE = ROOT / "scenes" / "panda_bottle.toml"


@pytest.fixture(scope="module")
def bottle() -> ou.Problem:
    return ou.load_scene(BOTTLE_SCENE)


def _with_mesh(problem: ou.Problem, name: str, z: float) -> ou.Problem:
    """The bottle scene with its object swapped for another shipped mesh, standing at
    height ``z`` [m] (its centre)."""
    assert problem.object is not None
    pose = problem.object.pose.copy()
    pose[2] = z
    shape = dataclasses.replace(
        problem.object, file=ROOT / "scenes" / "meshes" / f"{name}.obj", pose=pose
    )
    return dataclasses.replace(problem, object=shape)


def test_a_mesh_symmetry_is_read_from_its_hull(bottle: ou.Problem) -> None:
    """The bottle, vase and cup are solids of revolution about z; the pebble is not."""
    for name in ("bottle", "vase", "cup"):
        nominal = nominal_of(_with_mesh(bottle, name, 0.1).object)  # type: ignore[arg-type]
        assert (nominal.symmetry, nominal.axis) == ("axis", 2), name
    pebble = nominal_of(_with_mesh(bottle, "pebble", 0.1).object)  # type: ignore[arg-type]
    assert pebble.symmetry == "none"
    np.testing.assert_allclose(nominal_of(bottle.object).half, [0.033, 0.033, 0.1], atol=1e-3)  # type: ignore[arg-type]


@pytest.mark.parametrize("noise", [1.0, 4.0])
def test_a_mesh_object_is_perceived_within_millimetres(bottle: ou.Problem, noise: float) -> None:
    """The bottle's estimate lies within 3 mm of the truth, upright, with a finite
    covariance that has no variance about its axis of revolution."""
    seen = perceive(
        bottle,
        noise=NoiseOptions(scale=noise),
        rng=np.random.default_rng(3),
        options=PerceptionOptions.exact(),
    )
    assert bottle.object is not None
    assert np.linalg.norm(seen.pose[:3] - bottle.object.pose[:3]) < 0.003
    rotation = pin.XYZQUATToSE3(seen.pose).rotation
    assert rotation[2, 2] > np.cos(np.radians(3))  # upright within 3 degrees
    # The turn about the axis is not measured: the scene's is kept.
    assert abs(rotation[1, 0]) < 0.06
    assert np.all(np.isfinite(seen.position_covariance))
    assert np.linalg.eigvalsh(seen.position_covariance).min() > 0
    axis = rotation[:, 2]
    assert axis @ seen.rotation_covariance @ axis < 1e-12
    assert 0.0 < seen.u <= 1.0


def test_perceive_cli_writes_a_mesh_scene(tmp_path: Path) -> None:
    """``openup-ompl perceive`` on the bottle scene writes a pose and covariances."""
    assert main(["perceive", str(BOTTLE_SCENE), "--seed", "2", "--out", str(tmp_path)]) == 0
    # The default calibration errors: within their 5 mm and 0.5 degree (at 0.8 m) sigmas.
    summary = json.loads((tmp_path / "perception.json").read_text())
    for key in ("pose", "u", "position_covariance", "rotation_covariance"):
        assert key in summary
    assert np.linalg.norm(np.subtract(summary["pose"][:3], summary["true_pose"][:3])) < 0.04
    assert ou.load_scene(tmp_path / "perceived.toml").object.shape == "mesh"  # type: ignore[union-attr]


def test_the_expected_excess_over_a_round_hull_is_its_curvature_term() -> None:
    """A point on a finely faceted 40 mm ball under isotropic noise of 2 mm lies outside it
    by sigma^2 / r = 0.1 mm on average (the unscented transform's offset), on a face's
    plane by 0 (a flat face has no curvature)."""
    from openup_ompl.perception.noise import noise_covariance
    from openup_ompl.perception.registration import _expected_offsets, _planes

    k = np.arange(4000) + 0.5
    polar, turn = np.arccos(1 - 2 * k / k.size), np.pi * (1 + 5**0.5) * k
    ball = 0.04 * np.column_stack(
        [np.sin(polar) * np.cos(turn), np.sin(polar) * np.sin(turn), np.cos(polar)]
    )
    point = np.array([[0.0, 0.0, 0.04]])
    spread = np.eye(3)[None] * 0.002**2
    offset = _expected_offsets(point, pin.SE3.Identity(), _planes(ball), spread)
    assert offset[0] == pytest.approx(0.002**2 / 0.04, rel=0.1)
    cube = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * 0.04
    on_face = np.array([[0.0, 0.0, 0.04]])
    assert _expected_offsets(on_face, pin.SE3.Identity(), _planes(cube), spread)[0] == (
        pytest.approx(0.0, abs=1e-9)
    )
    # The sensor's covariance: lateral, lateral, axial in the camera's frame.
    covariance = noise_covariance(np.zeros(3), np.eye(3), NoiseOptions(scale=1.0))
    face_on = covariance(np.array([[0.0, 0.0, 1.0]]), np.array([[0.0, 0.0, -1.0]]))[0]
    assert face_on[2, 2] > face_on[0, 0] == pytest.approx(face_on[1, 1])
