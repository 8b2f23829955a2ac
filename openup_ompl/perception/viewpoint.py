"""``--camera auto``: the configured view if it sees the object whole, else the best of a
ring of candidate views around it.

A view sees the object whole when a noise-free look through it passes the checks
:func:`~openup_ompl.perception.perceive.perceive` refuses a view by
(:func:`~openup_ompl.perception.view.checked_view`: some object points, enough for the
fit, none on the image border, no side of its outline hidden behind a nearer surface with
nothing to bound it). The ring stands at the configured camera's distance from the object,
above it (elevations :data:`ELEVATIONS`), every :data:`AZIMUTH_STEP` degrees around; of
the views that pass, the one whose object outline is most bounded by a measured surface
behind it wins (:func:`~openup_ompl.perception.view.bounded_outline`: neither hidden by an
occluder nor beside pixels without a measurement; ties: the nearest in azimuth, then
elevation, to the configured view). Of the :data:`FITTED` best, the one whose fits (seeds
0 and 1) are nearest the scene's dimensions is used (a view can bound the outline and still
leave the fit a wrong minimum).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from openup_ompl.exceptions import NoViewSeesObject, PerceptionError
from openup_ompl.perception.camera import CameraOptions, DepthCamera
from openup_ompl.perception.noise import NoiseOptions, noisy_cloud
from openup_ompl.perception.view import bounded_outline, checked_view
from openup_ompl.scene import Problem

__all__ = ["AZIMUTH_STEP", "ELEVATIONS", "ViewChoice", "choose_camera"]

#: The ring's elevations [deg] above the object's centre.
ELEVATIONS = (40.0, 20.0, 60.0, 75.0)
#: The ring's azimuth step [deg].
AZIMUTH_STEP = 30.0
#: The best views by outline that are fitted to pick the one whose fit matches the
#: scene's dimensions best (a view can bound the outline and still leave the fit a wrong
#: minimum: README, Perception).
FITTED = 6


@dataclass(frozen=True)
class ViewChoice:
    """The camera ``--camera auto`` looks through.

    Attributes:
        camera: The chosen view's camera.
        options: Its options.
        configured: Whether it is the configured view.
        reason: Why the configured view was refused (None when it is used).
        tried: Candidate views tried (the configured one included).
        seeing: Of those, the views that see the object whole.
    """

    camera: DepthCamera
    options: CameraOptions
    configured: bool
    reason: str | None
    tried: int
    seeing: int

    def describe(self) -> str:
        """One line saying which view is used and why.

        Returns:
            The line (angles [deg], distance [m]).
        """
        if self.configured:
            return "camera: the configured view sees the object"
        o = self.options
        return (
            f"camera auto: the configured view does not see the object whole ({self.reason});"
            f" using elevation {o.elevation:g} deg, azimuth {o.azimuth:g} deg at"
            f" {o.distance:g} m ({self.seeing} of {self.tried - 1} ring views see it)"
        )


def _look(camera: DepthCamera) -> tuple[int | None, str]:
    """The object's outline pixels bounded by a measured surface behind it through
    ``camera`` (noise-free; :func:`~openup_ompl.perception.view.bounded_outline`), or None
    and the refusal's reason when the view does not see it whole."""
    noise = NoiseOptions(scale=0.0)
    view = camera.render()
    cloud = noisy_cloud(view, noise, np.random.default_rng(0))
    try:
        checked_view(camera.problem, camera, view, cloud, noise, True)
    except PerceptionError as error:
        return None, str(error).split(":")[0]
    return bounded_outline(view, noise), ""


def choose_camera(problem: Problem, configured: CameraOptions) -> ViewChoice:
    """The ``--camera auto`` view of ``problem``'s object (see the module docstring).

    Args:
        problem: The scene; its object is where it truly is.
        configured: The scene's camera (its ``[camera]`` table and overrides).

    Returns:
        The view chosen: its camera and options, whether it is the configured one, and
        how many ring views were tried and saw the object.

    Raises:
        NoViewSeesObject: Neither the configured view nor any of the ring sees the object
            whole.
    """
    first = DepthCamera(problem, configured)
    seen, reason = _look(first)
    if seen is not None:
        return ViewChoice(first, configured, True, None, 1, 1)
    home = configured.azimuth
    if home is None:  # towards the robot's base, as CameraOptions.look_at
        target = first.target
        home = math.degrees(math.atan2(-target[1], -target[0]))
    ring = [
        (elevation, home + step * AZIMUTH_STEP)
        for elevation in ELEVATIONS
        for step in range(int(360 / AZIMUTH_STEP))
    ]
    passing: list[tuple[tuple[float, ...], DepthCamera, CameraOptions]] = []
    for elevation, azimuth in ring:
        options = dataclasses.replace(
            configured,
            position=None,
            target=None,
            elevation=elevation,
            azimuth=round((azimuth + 180.0) % 360.0 - 180.0, 6),
        )
        camera = first.looking_from(options)
        seen, _ = _look(camera)
        if seen is None:
            continue
        turn = abs((azimuth - home + 180.0) % 360.0 - 180.0)
        passing.append(((seen, -turn, -abs(elevation - configured.elevation)), camera, options))
    if not passing:
        assert problem.object is not None
        raise NoViewSeesObject(problem.object.name, len(ring) + 1, reason)
    passing.sort(key=lambda candidate: candidate[0], reverse=True)
    scored = [(_mismatch(problem, camera), rank) for rank, (_, camera, _) in enumerate(passing)]
    _, rank = min(scored[:FITTED])
    _, camera, options = passing[rank]
    return ViewChoice(camera, options, False, reason, len(ring) + 1, len(passing))


def _mismatch(problem: Problem, camera: DepthCamera) -> float:
    """How far fits through ``camera`` (the sensor's noise, seeds 0 and 1; the worse) are
    from the scene's dimensions: the sum of the log ratios of the sorted fitted and
    nominal half-sizes (inf: refused)."""
    from openup_ompl.perception.extrinsic import PerceptionOptions
    from openup_ompl.perception.nominal import nominal_of
    from openup_ompl.perception.perceive import perceive

    assert problem.object is not None
    nominal = np.sort(nominal_of(problem.object).half)
    worst = 0.0
    for seed in (0, 1):
        try:
            seen = perceive(
                problem,
                depth_camera=camera,
                rng=np.random.default_rng(seed),
                options=PerceptionOptions.exact(),
            )
        except PerceptionError:
            return math.inf
        fitted = np.sort(seen.fit.superquadric.sizes)
        worst = max(worst, float(np.sum(np.abs(np.log(fitted / nominal)))))
    return worst
