"""A solid the scene names is fitted as that solid (issue 34): its exponents held, each
point's residual its exact distance to the box, the cylinder or the ball, not to the
superquadric whose rounded edges grew the box into its outline's pixel."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

from openup_ompl.exceptions import ConfigError
from openup_ompl.perception import NoiseOptions, fit_superquadric, perceive
from openup_ompl.perception.calibration import calibration_scene
from openup_ompl.perception.extrinsic import PerceptionOptions
from openup_ompl.perception.superquadric import _distance, _solid_distance

SIZES = np.array([0.025, 0.04, 0.06])


def test_the_box_distance_is_euclidean_and_its_edges_sharp() -> None:
    """On a face up to its edge 0, beyond a corner the Euclidean distance, inside the
    nearest face's; the sharpest superquadric puts a face's point near the edge outside."""
    near_edge = np.array([[0.025, 0.039, 0.0]])  # on the x face, 1 mm from its edge
    corner = np.array([[0.026, 0.041, 0.061]])  # 1 mm beyond the corner on each axis
    inside = np.array([[0.020, 0.0, 0.0]])  # 5 mm behind the x face
    assert _solid_distance(near_edge, SIZES, "box")[0] == pytest.approx(0.0, abs=1e-12)
    assert _solid_distance(corner, SIZES, "box")[0] == pytest.approx(math.sqrt(3) * 1e-3)
    assert _solid_distance(inside, SIZES, "box")[0] == pytest.approx(-0.005)
    assert _distance(near_edge, SIZES, 0.05, 0.05)[0] > 1e-4


def test_the_cylinder_and_the_ball_distances() -> None:
    """A cylinder's side, end and rim, a ball's surface: their Euclidean distances."""
    sizes = np.array([0.03, 0.03, 0.08])
    side = np.array([[0.032, 0.0, 0.0]])
    end = np.array([[0.0, 0.01, -0.083]])
    rim = np.array([[0.0, 0.033, 0.084]])
    assert _solid_distance(side, sizes, "cylinder")[0] == pytest.approx(0.002)
    assert _solid_distance(end, sizes, "cylinder")[0] == pytest.approx(0.003)
    assert _solid_distance(rim, sizes, "cylinder")[0] == pytest.approx(0.005)
    ball = np.array([[0.0, 0.03, 0.04]])
    assert _solid_distance(ball, np.full(3, 0.04), "sphere")[0] == pytest.approx(0.01)


def test_an_unknown_solid_is_refused() -> None:
    """A solid the fit does not know names itself."""
    points = np.random.default_rng(0).normal(size=(40, 3))
    with pytest.raises(ConfigError, match="solid"):
        fit_superquadric(points, solid="cone")


@pytest.mark.parametrize("name", ["box", "cylinder", "stick"])
def test_a_noise_free_view_sizes_the_solid(name: str) -> None:
    """The calibration scene's box and cans seen without noise: half-sizes within 0.1 mm of
    the scene's (the superquadric grew the box's by 1.5 mm), exponents the solid's."""
    problem = calibration_scene(name)
    seen = perceive(
        problem,
        noise=NoiseOptions(scale=0.0),
        rng=np.random.default_rng(1),
        options=PerceptionOptions.exact(),
    )
    assert problem.object is not None
    if name == "box":
        assert problem.object.size is not None
        expected = np.sort(problem.object.size / 2)
    else:
        radius, length = problem.object.radius, problem.object.length
        assert radius is not None and length is not None
        expected = np.sort([radius, radius, length / 2])
    sizes = np.sort(seen.fit.superquadric.sizes)
    assert np.all(np.abs(sizes - expected) < 1e-4), (sizes, expected)
    e1, e2 = seen.fit.superquadric.exponents
    assert e1 == pytest.approx(0.05, abs=1e-5)
    assert e2 == pytest.approx(0.05 if name == "box" else 1.0, abs=1e-5)


def test_a_ball_is_fitted_round_at_high_noise() -> None:
    """The ball at noise 4 keeps its exponents at 1 (free, they reached 0.3-1.9 and moved
    the centre up to 10 mm towards the camera)."""
    seen = perceive(
        calibration_scene("sphere"),
        noise=NoiseOptions(scale=4.0),
        rng=np.random.default_rng(3),
        options=PerceptionOptions.exact(),
    )
    assert np.allclose(seen.fit.superquadric.exponents, 1.0, atol=1e-5)


#: The study's planks (``panda-thin``, ``perceived``, seed 2) whose fit ended lying on its
#: broad face, 130-180 mm off, or refused (trial 0), before the upright start.
PLANK_TRIALS = (0, 1, 3, 4, 7)


def test_the_study_plank_on_edge_is_estimated_standing() -> None:
    """The study's thin plank seen from the Panda's camera: the estimate stands on edge
    (its thin axis horizontal) and its position errs by under 20 mm in every trial (the
    superquadric fit's 90th percentile over 200 trials was 17.4 mm)."""
    from openup_ompl.study.errors import believe, parse_error
    from openup_ompl.study.families import instance_problem, parse_families, template_scene
    from openup_ompl.study.run import trial_seeds

    family = parse_families(["panda-thin"])[0]
    template = template_scene(family)
    source = parse_error("perceived")
    errors = []
    for trial in PLANK_TRIALS:
        instance_rng, error_rng, _ = trial_seeds(2, family.name, source.name, trial)
        truth = instance_problem(family, instance_rng, template)
        belief = believe(truth, source, error_rng)
        assert belief.believed is not None, (trial, belief.refusal)
        assert truth.object is not None and belief.believed.object is not None
        true, believed = truth.object.pose, belief.believed.object.pose
        thin_axis = pin.XYZQUATToSE3(believed).rotation[:, 1]
        assert abs(thin_axis[2]) < 0.2, (trial, thin_axis)
        errors.append(float(np.linalg.norm(believed[:3] - true[:3])))
    assert max(errors) < 0.020, errors
