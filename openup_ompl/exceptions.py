"""Exception hierarchy: every error this package raises derives from :class:`OpenUpError`.

Each class carries the data needed to debug it (the bad value, what was expected), so a
caller can react programmatically and the command line can print one clear line.
"""

from __future__ import annotations

import math
from collections.abc import Sequence


class OpenUpError(Exception):
    """Base class of every error raised by openup-ompl."""


class ConfigError(OpenUpError, ValueError):
    """A robot file, scene file or option holds a value that is not what was expected.

    Attributes:
        where: File and key (or option name) holding the bad value.
        value: The bad value as read.
        expected: What would have been accepted.
    """

    def __init__(self, where: str, value: object, expected: str) -> None:
        self.where = where
        self.value = value
        self.expected = expected
        super().__init__(f"{where}: got {value!r}, expected {expected}")


class RobotNotFound(OpenUpError, LookupError):
    """No robot definition of that name or path exists.

    Attributes:
        name: The requested robot.
        available: The robot names that do exist.
    """

    def __init__(self, name: str, available: Sequence[str]) -> None:
        self.name = name
        self.available = list(available)
        super().__init__(
            f"unknown robot {name!r}: expected one of {self.available} or a path to a robot TOML"
        )


class JointNotFound(OpenUpError, LookupError):
    """A joint named in a robot definition does not exist in its URDF.

    Attributes:
        name: The joint asked for.
        joints: The joints the model has.
    """

    def __init__(self, name: str, joints: Sequence[str]) -> None:
        self.name = name
        self.joints = list(joints)
        super().__init__(f"unknown joint {name!r}: the URDF has {self.joints}")


class FrameNotFound(OpenUpError, LookupError):
    """A frame named in a robot definition does not exist in its URDF.

    Attributes:
        name: The frame asked for.
        frames: The frames the model has.
    """

    def __init__(self, name: str, frames: Sequence[str]) -> None:
        self.name = name
        self.frames = list(frames)
        super().__init__(f"unknown frame {name!r}: the URDF has {self.frames}")


class InvalidProblem(OpenUpError):
    """The planning problem cannot have a valid solution as posed.

    Raised before planning for a start in collision or outside the joint limits, a grasp
    pose out of reach or reachable only in collision, or a start already at the grasp.
    """


class UnreachableGrasp(InvalidProblem):
    """No collision-free inverse-kinematics solution of the grasp pose was found.

    Attributes:
        pose: The grasp pose ``[x, y, z, qx, qy, qz, qw]`` in the world frame.
        attempts: IK restarts tried.
        in_collision: How many of the IK solutions found were rejected for collision.
        margin: The clearance [m] a solution needed.
        pairs: Geometry pairs in contact at one rejected solution.
    """

    def __init__(
        self,
        pose: Sequence[float],
        attempts: int,
        in_collision: int,
        margin: float = 0.0,
        pairs: Sequence[tuple[str, str]] = (),
    ) -> None:
        self.pose = list(pose)
        self.attempts = attempts
        self.in_collision = in_collision
        self.margin = margin
        self.pairs = list(pairs)
        if in_collision:
            example = f"; e.g. {self.pairs[:3]}" if self.pairs else ""
            why = (
                f"reachable only in collision ({in_collision} IK solutions with the hand at"
                f" its grasp opening, all colliding or closer than {margin * 1e3:.3g} mm{example})"
            )
            message = f"grasp pose {self.pose} is {why} after {attempts} IK restarts"
        else:
            # Random restarts can miss a pose reachable only in a sliver of joint space.
            message = (
                f"grasp pose {self.pose} is out of reach (no IK solution) after {attempts} IK"
                " restarts, or reachable only in a sliver of joint space they did not find"
            )
        super().__init__(message)


class PlanningFailed(OpenUpError):
    """The planner ended without an exact solution.

    Attributes:
        status: OMPL's planner status, as text in lower case with spaces (e.g.
            ``"timeout"``, ``"approximate solution"``).
        planner: The planner's name.
        time_limit: The time limit it was given [s].
    """

    def __init__(self, status: str, planner: str, time_limit: float) -> None:
        self.status = status
        self.planner = planner
        self.time_limit = time_limit
        super().__init__(
            f"{planner} found no exact solution within {time_limit} s (OMPL status: {status})"
        )


class VerifyFailed(PlanningFailed):
    """A path the planner returned fails its independent re-check (never expected from a
    correct planner: it points at a bug, not at a hard problem).

    Attributes:
        reason: What the re-check found (e.g. ``"path row 12 collides"``).
        planner: The planner that returned the path.
        status: The same as ``reason`` (no OMPL status: the planner had succeeded).
        time_limit: ``nan`` (not a matter of time).
    """

    def __init__(self, reason: str, planner: str = "") -> None:
        OpenUpError.__init__(self, f"the plan fails its re-check: {reason}")
        self.reason = reason
        self.status = reason
        self.planner = planner
        self.time_limit = math.nan


class MissingExtra(OpenUpError, ImportError):
    """An optional dependency is not installed.

    Attributes:
        module: The missing module.
        extra: The ``pip install 'openup-ompl[extra]'`` that brings it.
    """

    def __init__(self, module: str, extra: str) -> None:
        self.module = module
        self.extra = extra
        super().__init__(f"{module} is needed for this: pip install 'openup-ompl[{extra}]'")


class SweepFailed(OpenUpError):
    """Some tasks of a sweep failed on every attempt.

    Attributes:
        failures: Task key -> the last error message.
    """

    def __init__(self, failures: dict[str, str]) -> None:
        self.failures = dict(failures)
        first = next(iter(self.failures.items()))
        super().__init__(
            f"{len(self.failures)} task(s) failed on every attempt; first {first[0]!r}: {first[1]}"
        )


class PerceptionError(OpenUpError):
    """The simulated camera or the superquadric fit cannot give a pose estimate."""


class ObjectNotVisible(PerceptionError):
    """The camera's view holds no point of the object.

    Attributes:
        camera: The camera's position ``[x, y, z]`` [m] in the world frame.
        target: The point [m] it looks at.
        object_name: The scene object that was looked for.
        hits: Rays that hit anything (obstacles included).
        dropped: Object hits dropped at grazing incidence.
    """

    def __init__(
        self,
        camera: Sequence[float],
        target: Sequence[float],
        object_name: str,
        hits: int,
        dropped: int = 0,
    ) -> None:
        self.camera = [float(x) for x in camera]
        self.target = [float(x) for x in target]
        self.object_name = object_name
        self.hits = hits
        self.dropped = dropped
        where = ", ".join(f"{x:.3g}" for x in self.camera)
        at = ", ".join(f"{x:.3g}" for x in self.target)
        super().__init__(
            f"the camera at [{where}] looking at [{at}] sees no point of the object"
            f" {object_name!r} ({hits} rays hit the scene, {dropped} object hits dropped at"
            " grazing incidence): expected a camera that sees it"
        )


class _UnboundedView(PerceptionError):
    """A view that does not bound the object on some image sides (``"top"``,
    ``"bottom"``, ``"left"``, ``"right"``): :attr:`pixels` of its outline there."""

    #: What the message calls a side, and its start and remedy.
    noun = "side"
    opening = ""
    remedy = ""

    def __init__(self, pixels: int, sides: Sequence[str]) -> None:
        self.pixels = pixels
        self.sides = list(sides)
        named = f"{' and '.join(self.sides)} {self.noun}{'s' if len(self.sides) > 1 else ''}"
        super().__init__(self.opening.format(pixels=pixels, sides=named) + self.remedy)


class ObjectCutOff(_UnboundedView):
    """The object runs off the image: the view does not bound it, and the fit grows it
    past the border, far off with a small sigma.

    Attributes:
        pixels: The object's pixels on the image border.
        sides: The borders they lie on (``"top"``, ``"bottom"``, ``"left"``, ``"right"``).
    """

    noun = "border"
    opening = "the object runs off the image: {pixels} of its pixels on its {sides}"
    remedy = (
        ": expected the whole object in view (a wider field of view, or a camera further"
        " away or aimed at it)"
    )


class ObjectOccluded(_UnboundedView):
    """The object's outline is hidden behind a nearer surface on a side nothing else
    bounds: its extent there is unknown, and the fit ends it where the view does, far off
    with a small sigma. The bottom is bounded when the
    object stands on a surface the rays find (:meth:`~openup_ompl.perception.camera.
    DepthCamera.support_under`).

    Attributes:
        pixels: The object's outline pixels next to the occluder on those sides.
        sides: The image sides hidden (``"top"``, ``"bottom"``, ``"left"``, ``"right"``).
    """

    opening = (
        "the object is hidden behind a nearer surface on its {sides} ({pixels} outline pixels)"
    )
    remedy = (
        ": the view does not bound it there: expected a view that sees its outline (another"
        " elevation or azimuth)"
    )


class TooFewPoints(PerceptionError):
    """The object's point cloud has fewer points than the fit has parameters.

    Attributes:
        points: Points in the cloud.
        needed: The least number accepted.
    """

    def __init__(self, points: int, needed: int) -> None:
        self.points = points
        self.needed = needed
        super().__init__(
            f"the object's point cloud has {points} points: expected at least {needed}"
            " (more points than the superquadric's 11 parameters)"
        )


class DegenerateFit(PerceptionError):
    """The superquadric fit collapsed onto one face of the object: a half-size sits at the
    fit's lower bound, the object's extent along it unseen (a camera looking down on a
    can sees its top; the centre is then placed up to half its length off, with a
    sub-millimetre covariance).

    Attributes:
        sizes: The fitted half-sizes [m].
        bound: The fit's lower bound of a half-size [m].
    """

    def __init__(self, sizes: Sequence[float], bound: float) -> None:
        self.sizes = [float(x) for x in sizes]
        self.bound = float(bound)
        shown = ", ".join(f"{x * 1e3:.1f}" for x in self.sizes)
        super().__init__(
            f"the superquadric fit collapsed onto one face of the object: half-sizes [{shown}]"
            f" mm, one at the fit's bound {self.bound * 1e3:g} mm (the view shows no extent"
            " along it): expected a view of more than one face (from another side)"
        )


class NoViewSeesObject(PerceptionError):
    """Neither the configured camera nor any view of the ring around the object sees it
    whole (``--camera auto``).

    Attributes:
        object_name: The scene object looked for.
        views: Candidate views tried (the configured one included).
        reason: Why the configured view was refused.
    """

    def __init__(self, object_name: str, views: int, reason: str) -> None:
        self.object_name = object_name
        self.views = views
        self.reason = reason
        super().__init__(
            f"no view sees the object {object_name!r} whole: the configured camera's ({reason})"
            f" and the {views - 1} views of the ring around it (elevations and azimuths at"
            " its distance) are refused: expected a [camera] position that sees it"
        )


class SimulationDiverged(OpenUpError):
    """The physics simulation became unstable (MuJoCo reported a bad acceleration or a
    non-finite state) during a rollout: its verdict would be meaningless.

    Attributes:
        phase: The rollout phase (``settle``, ``reach``, ``close``, ``lift``, ``hold``).
        time: Simulated time [s] at which it was noticed.
        detail: What MuJoCo reported.
    """

    def __init__(self, phase: str, time: float, detail: str) -> None:
        self.phase = phase
        self.time = time
        self.detail = detail
        super().__init__(
            f"the physics simulation diverged during the {phase} at {time:.3f} s ({detail});"
            " try a smaller PhysicsOptions.timestep"
        )


class PlanRejected(ConfigError):
    """A plan fails its re-validation against its scene before use
    (:func:`~openup_ompl.revalidate.revalidate_plan`): a stale or edited plan is never run.

    Attributes:
        row: Index of the first bad state in the plan's path.
        reason: What is wrong with it.
    """

    def __init__(self, where: str, row: int, reason: str, expected: str) -> None:
        self.row = int(row)
        self.reason = reason
        self.where, self.value, self.expected = f"{where}path[{self.row}]", reason, expected
        OpenUpError.__init__(self, f"{self.where}: {reason}; expected {expected}")


class NativeUnavailable(OpenUpError, ImportError):
    """The compiled coupled check cannot be used here (:mod:`openup_ompl.native`): it is
    not built for the pinocchio, coal and Python in use, it was built against other
    versions of them, or it would not be exact for the law asked for.

    Attributes:
        reason: Why it cannot be used.
        remedy: What would make it usable (e.g. ``openup-ompl build-native``).
    """

    def __init__(self, reason: str, remedy: str) -> None:
        self.reason = reason
        self.remedy = remedy
        super().__init__(f"the compiled coupled check is unavailable: {reason}; {remedy}")


class NativeBuildError(OpenUpError, RuntimeError):
    """Building the compiled coupled check failed (``openup-ompl build-native``).

    Attributes:
        step: The step that failed: ``"compiler"``, ``"headers"``, ``"eigen"``,
            ``"compile"`` or ``"load"``.
        detail: What went wrong (the tool's last lines of output where there are some).
        remedy: What to do about it.
    """

    def __init__(self, step: str, detail: str, remedy: str) -> None:
        self.step = step
        self.detail = detail
        self.remedy = remedy
        super().__init__(f"building the compiled check failed at '{step}': {detail}; {remedy}")
