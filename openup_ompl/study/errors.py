"""The study's error sources: where the planner believes the object is.

- ``pose-<sigma>cm`` (``pose-0.5cm``, ``pose-1cm``, ``pose-2cm``, any sigma): a direct pose
  error in the style of Dex-Net's robustness sampling: the believed object is the true one
  moved by a Gaussian error of standard deviation ``sigma`` along the world x and y axes,
  and turned about its own z axis by a Gaussian yaw of :data:`YAW_SIGMA`. The policies
  know ``sigma`` (their evidence is that covariance).
- ``perceived`` or ``perceived-<scale>``: the simulated depth camera of
  :mod:`openup_ompl.perception` (the scene's camera, or its default pose) with its sensor
  noise model at ``scale`` (1: the Kinect v1's), its default calibration errors
  (:class:`~openup_ompl.perception.extrinsic.PerceptionOptions`: the camera's extrinsic
  pose off by 5 mm and 0.5 deg, a 2 mm depth bias, drawn per view), the fit and its
  covariance. A view the perception step refuses (object occluded, cut off, too few
  points) leaves the trial without an estimate: nothing is planned and every policy fails
  it (counted as ``not_seen``).

The plan is made at the believed pose (the grasp moves with the object:
:func:`~openup_ompl.perception.perceive.at_estimate`); execution is always against the
true pose.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from openup_ompl.exceptions import ConfigError, PerceptionError
from openup_ompl.perception.perceive import at_estimate
from openup_ompl.scene import Problem
from openup_ompl.study.policies import Evidence, shape_diameter

__all__ = ["DEFAULT_ERRORS", "YAW_SIGMA", "Belief", "ErrorSource", "believe", "parse_error"]

#: Standard deviation [rad] of the direct error's yaw about the object's own z axis.
YAW_SIGMA = 0.05
#: The study's error sources, in table order.
DEFAULT_ERRORS = ("pose-0.5cm", "pose-1cm", "pose-2cm", "perceived")
#: Largest direct error sigma [m] accepted.
MAX_SIGMA = 0.1
#: Largest sensor noise scale accepted.
MAX_NOISE = 20.0

_POSE = re.compile(r"^pose-(\d+(?:\.\d+)?)cm$")
_PERCEIVED = re.compile(r"^perceived(?:-(\d+(?:\.\d+)?))?$")


@dataclass(frozen=True)
class ErrorSource:
    """An error source.

    Attributes:
        name: As given (``pose-1cm``, ``perceived-2``).
        kind: ``"pose"`` or ``"perceived"``.
        sigma: The direct error's standard deviation [m] (``pose`` only).
        noise: The sensor noise scale (``perceived`` only).
    """

    name: str
    kind: str
    sigma: float = 0.0
    noise: float = 1.0


def parse_error(name: str) -> ErrorSource:
    """An error source from its name.

    Args:
        name: ``pose-<sigma>cm`` (a planar pose error of standard deviation ``sigma``
            [cm] per axis) or ``perceived[-<scale>]`` (perception with the sensor noise
            scaled by ``scale``).

    Returns:
        The error source (``sigma`` stored in [m]).

    Raises:
        ConfigError: Not ``pose-<sigma>cm`` or ``perceived[-<scale>]``, or a value out of
            range.
    """
    expected = "pose-<sigma>cm (e.g. pose-1cm) or perceived[-<noise scale>]"
    text = str(name)
    pose, seen = _POSE.match(text), _PERCEIVED.match(text)
    if pose is not None:
        sigma = float(pose.group(1)) / 100
        if not 0 < sigma <= MAX_SIGMA:
            raise ConfigError("error", name, f"a sigma in (0, {MAX_SIGMA * 100:g}] cm")
        return ErrorSource(text, "pose", sigma=sigma)
    if seen is not None:
        noise = float(seen.group(1)) if seen.group(1) else 1.0
        if not 0 < noise <= MAX_NOISE:
            raise ConfigError("error", name, f"a noise scale in (0, {MAX_NOISE:g}]")
        return ErrorSource(text, "perceived", noise=noise)
    raise ConfigError("error", name, expected)


@dataclass(frozen=True)
class Belief:
    """A trial's belief: the problem as planned and the policies' evidence (``None``
    both when perception refused the view: ``refusal`` says why).

    Attributes:
        believed: The problem with the object (and grasp) at the estimate.
        evidence: What the policies know of the error.
        offset: The estimate's planar error from the truth ``(dx, dy, yaw)`` [m, m, rad].
        refusal: Why there is no estimate.
    """

    believed: Problem | None
    evidence: Evidence | None
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    refusal: str | None = None


def _yawed(pose: np.ndarray, dx: float, dy: float, yaw: float) -> np.ndarray:
    placement = pin.XYZQUATToSE3(pose)
    turned = placement.rotation @ pin.utils.rotate("z", yaw)
    moved = pin.SE3(turned, placement.translation + np.array([dx, dy, 0.0]))
    return np.asarray(pin.SE3ToXYZQUAT(moved), dtype=float)


def believe(truth: Problem, source: ErrorSource, rng: np.random.Generator) -> Belief:
    """Draw a trial's estimate of the true problem's object.

    Args:
        truth: The problem as it really is.
        source: The error source.
        rng: The trial's error generator (its draws: ``dx, dy, yaw`` or the sensor noise).

    Returns:
        The belief: the problem at the estimate and the policies' evidence, or a refusal.
    """
    shape = truth.object
    assert shape is not None
    if source.kind == "pose":
        dx, dy = rng.normal(0.0, source.sigma, 2)
        yaw = float(rng.normal(0.0, YAW_SIGMA))
        believed = at_estimate(truth, _yawed(shape.pose, float(dx), float(dy), yaw))
        position = np.diag([source.sigma**2, source.sigma**2, 0.0])
        rotation = np.diag([0.0, 0.0, YAW_SIGMA**2])
        evidence = Evidence(position, rotation, shape_diameter(shape), source.sigma)
        return Belief(believed, evidence, (-float(dx), -float(dy), -yaw))
    return _perceived(truth, source, rng)


def _perceived(truth: Problem, source: ErrorSource, rng: np.random.Generator) -> Belief:
    from openup_ompl.perception.closed_loop import planar_offset
    from openup_ompl.perception.noise import NoiseOptions
    from openup_ompl.perception.perceive import perceive

    assert truth.object is not None
    try:
        seen = perceive(truth, noise=NoiseOptions(scale=source.noise), rng=rng)
    except PerceptionError as error:
        return Belief(None, None, refusal=f"{type(error).__name__}: {error}")
    believed = at_estimate(truth, seen.pose)
    fit = seen.fit
    # The perception's pose covariance: the fit's (a mesh's registration's) with the
    # camera's calibration errors, none about a symmetry axis; in the scene shape's frame,
    # so the scene's extents go with it (sizes None), not the superquadric's.
    evidence = Evidence(
        seen.position_covariance,
        seen.rotation_covariance,
        fit.diameter,
        fit.mean_residual,
        sizes=None,
        perceived=True,
    )
    assert believed.object is not None and truth.object is not None
    offset = planar_offset(believed.object, truth.object)
    if not all(math.isfinite(x) for x in offset):
        return Belief(None, None, refusal="non-finite estimate")
    return Belief(believed, evidence, offset)
