"""Settings of a physics rollout: one frozen object, every number with its unit."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

from openup_ompl._toml import is_finite
from openup_ompl.exceptions import ConfigError
from openup_ompl.scene import MIN_MASS

__all__ = ["PHASE_MAX", "PhysicsOptions"]

#: The options that are True or False.
FLAGS = ("pads", "early_end", "shared_approach")
#: The longest phase of a rollout [s of simulated time]: a bound on the settle, the
#: squeeze, the lift, the hold, the reach and the closing (a longer one is a typo, and
#: would run for hours).
PHASE_MAX = 60.0
#: Upper bounds of options whose size sets the work of a rollout: (name, bound, unit).
LARGEST = (
    ("settle", PHASE_MAX, "s"),
    ("close_settle", PHASE_MAX, "s"),
    ("hold", PHASE_MAX, "s"),
    ("lift_height", 1.0, "m"),
    ("object_jitter", 0.1, "m"),
)


@dataclass(frozen=True)
class PhysicsOptions:
    """How a plan is executed in MuJoCo (:func:`~openup_ompl.physics.rollout.execute_plan`).

    Gains are those of MuJoCo position actuators (``force = kp (target - q) - kv qdot``,
    clipped to the force limit); revolute joints take N m / rad, prismatic ones N / m.
    Defaults were tuned on the three shipped robots (``tests/test_physics.py`` bounds the
    tracking error they give).

    Attributes:
        timestep: Simulation step [s] (``implicitfast`` integrator).
        contact_timeconst: Time constant [s] of the object's contacts (MuJoCo's
            ``solref[0]``; the object's contacts use its parameters). MuJoCo's default,
            0.02 s, lets the fingers sink into the can under the squeeze; 0.004 s is twice
            the timestep, the stiffest MuJoCo advises.
        contact_solimp: The object's ``solimp`` (impedance at zero and full depth, the
            depth [m] between them, midpoint, power).
        impratio: MuJoCo's ratio of frictional to normal constraint impedance (with
            elliptic cones; > 1 lets held objects creep less in the fingers).
        arm_kp: Arm position gain [N m / rad].
        arm_kv: Arm velocity gain [N m s / rad].
        arm_armature: Reflected rotor inertia added to every arm joint [kg m^2]; with
            ``implicitfast`` it keeps stiff position loops stable at ``timestep``.
        arm_force_limit: Arm torque limit [N m] for joints whose URDF gives no effort
            limit (otherwise the URDF's ``effort``).
        hand_kp: Hand position gain [N m / rad] (revolute hand joints).
        hand_kv: Hand velocity gain [N m s / rad] (revolute hand joints).
        finger_kp: Hand position gain [N / m] (prismatic hand joints, e.g. the Panda's).
        finger_kv: Hand velocity gain [N s / m] (prismatic hand joints).
        hand_armature: Armature of every hand joint [kg m^2 or kg].
        squeeze_torque: Torque limit of a revolute hand joint [N m]: what it presses
            with once its target has gone past the contact.
        squeeze_force: Force limit of a prismatic hand joint [N] (per finger).
        speed: Fraction of the URDF velocity limits the reach moves at (the slowest
            joint of each segment sets its duration).
        acceleration: Joint acceleration limit [rad/s^2 or m/s^2] of the reach's timing
            (along the path and where it turns).
        velocity_limit: Velocity limit [rad/s or m/s] of joints whose URDF gives none.
        close_speed: Speed [rad/s] at which the targets of revolute hand joints move
            towards the closed configuration (times the robot's ``closing_speed``).
        finger_close_speed: The same for prismatic hand joints [m/s].
        close_settle: Time [s] the hand keeps squeezing after every target has reached
            the closed configuration, before the lift.
        lift_height: Straight-up palm motion of the lift [m] (world z).
        lift_speed: Mean palm speed of the lift [m/s] (a smoothstep in time: 1.5 times
            that at its middle).
        hold: Time [s] the object is held at the top before the verdict.
        settle: Time [s] the object rests on the scene before the reach starts.
        success_distance: Largest drift [m] of the object in the palm frame between the
            end of closing and the end of the hold for a held grasp.
        success_angle: Largest rotation [rad] of the object in the palm frame over the
            same interval.
        lifted_fraction: The object must rise by at least this fraction of
            ``lift_height`` over the lift and hold.
        max_penetration: Deepest object-obstacle penetration [m] a trial may show; deeper,
            the hand forced the object into the scene (where a real arm would stall or
            the object break), which fails the trial as ``"jammed"`` instead of letting
            it tunnel through the table.
        object_friction: Object sliding friction; ``None``: the scene's ``[object]
            friction``.
        object_mass: Object mass [kg]; ``None``: the scene's ``[object] mass``.
        object_jitter: Standard deviation [m] of a random horizontal shift of the object
            drawn from the run's seed (0: none; the rollout is then deterministic and the
            seed only recorded).
        frame_period: Period [s] of the frames kept for the viewer.
        neighbour_moved_distance: A movable obstacle displaced by more than this [m]
            between the end of the settle and the end of the rollout was moved.
        neighbour_tipped_angle: One whose up axis (its own z) turned by more than this
            [rad] over the same interval was tipped.
        pads: Use the robot file's contact pads (``[physics] pads``); ``False``: the
            URDF's collision geometry makes every contact (as before pads existed).
        early_end: End a rollout once its verdict is certain: at a robot link's first
            touch of a fixed obstacle (when the scene has no movable obstacle, whose
            disturbance is still to come), or during the hold once no link touches the
            object and it and every neighbour have rested for 0.15 s (``dropped`` or ``no
            contact``). The verdict is the full rollout's (tested on 126 trials); the
            record's numbers are those at the end (``ExecutionRecord.ended_early``).
            Sweeps and the closed loop's judge set it; ``execute`` does not.
        shared_approach: A :class:`~openup_ompl.physics.rollout.Rollout`'s trials share
            the settle, the reach and the close up to where each trial's hand may first
            reach its object (:mod:`~openup_ompl.physics.approach`): the robot's motion
            is the same to the last bit, the resting object's equal up to rounding, so a
            record's numbers may differ from the unshared run's (much, in a grasp that
            rounding sends another way; the verdicts of the 146 fixed trials are the
            same). For many offsets of one plan (``robustness --shared-approach``); no
            gain for one trial per plan.
    """

    timestep: float = 0.002  # [s]
    contact_timeconst: float = 0.004  # [s]
    contact_solimp: tuple[float, float, float, float, float] = (0.95, 0.99, 0.001, 0.5, 2.0)
    impratio: float = 10.0
    arm_kp: float = 2000.0  # [N m / rad]
    arm_kv: float = 100.0  # [N m s / rad]
    arm_armature: float = 0.1  # [kg m^2]
    arm_force_limit: float = 100.0  # [N m]
    hand_kp: float = 20.0  # [N m / rad]
    hand_kv: float = 0.5  # [N m s / rad]
    finger_kp: float = 2000.0  # [N / m]
    finger_kv: float = 40.0  # [N s / m]
    hand_armature: float = 0.01  # [kg m^2] or [kg]
    squeeze_torque: float = 1.0  # [N m]
    squeeze_force: float = 20.0  # [N]
    speed: float = 0.5  # [fraction of the URDF velocity limits]
    acceleration: float = 2.0  # [rad/s^2] or [m/s^2]
    velocity_limit: float = 1.0  # [rad/s] or [m/s]
    close_speed: float = 1.0  # [rad/s]
    finger_close_speed: float = 0.05  # [m/s]
    close_settle: float = 0.4  # [s]
    lift_height: float = 0.10  # [m]
    lift_speed: float = 0.1  # [m/s]
    hold: float = 2.0  # [s]
    settle: float = 0.1  # [s]
    success_distance: float = 0.05  # [m]
    success_angle: float = math.radians(15.0)  # [rad]
    lifted_fraction: float = 0.5
    max_penetration: float = 0.005  # [m]
    object_friction: float | None = None
    object_mass: float | None = None
    object_jitter: float = 0.0  # [m]
    frame_period: float = 0.02  # [s]
    neighbour_moved_distance: float = 0.02  # [m]
    neighbour_tipped_angle: float = math.radians(45.0)  # [rad]
    pads: bool = True
    early_end: bool = False
    shared_approach: bool = False

    def __post_init__(self) -> None:
        solimp = self.contact_solimp
        if not (
            isinstance(solimp, (tuple, list))
            and len(solimp) == 5
            and all(is_finite(x) for x in solimp)
            and 0 < solimp[0] <= solimp[1] < 1
            and solimp[2] > 0
            and 0 < solimp[3] < 1
            and solimp[4] >= 1
        ):
            # MuJoCo's impedance: d0 to dwidth over width [m], a sigmoid whose midpoint lies
            # in (0, 1) and whose power is at least 1 (MuJoCo clamps other values silently).
            raise ConfigError(
                "PhysicsOptions.contact_solimp",
                solimp,
                "(d0, dwidth, width, mid, power), 0 < d0 <= dwidth < 1, width > 0,"
                " 0 < mid < 1, power >= 1",
            )
        for flag in FLAGS:
            if not isinstance(getattr(self, flag), bool):
                raise ConfigError(f"PhysicsOptions.{flag}", getattr(self, flag), "True or False")
        for item in fields(self):
            if item.name == "contact_solimp" or item.name in FLAGS:
                continue
            value = getattr(self, item.name)
            if value is None and item.name in ("object_friction", "object_mass"):
                continue
            zero_ok = item.name in (
                "settle",
                "close_settle",
                "hold",
                "object_jitter",
                "arm_armature",
                "hand_armature",
                "hand_kv",
                "finger_kv",
                "arm_kv",
                "object_friction",
            )
            if not (is_finite(value) and (value >= 0 if zero_ok else value > 0)):
                expected = "a number >= 0" if zero_ok else "a positive number"
                raise ConfigError(f"PhysicsOptions.{item.name}", value, expected)
        if self.contact_timeconst < 2 * self.timestep:
            raise ConfigError(
                "PhysicsOptions.contact_timeconst",
                self.contact_timeconst,
                f"at least twice the timestep ({2 * self.timestep:g} s)",
            )
        if self.object_mass is not None and self.object_mass < MIN_MASS:
            raise ConfigError(
                "PhysicsOptions.object_mass", self.object_mass, f"a mass >= {MIN_MASS:g} kg"
            )
        for name, most, unit in LARGEST:
            value = getattr(self, name)
            if value > most:
                raise ConfigError(f"PhysicsOptions.{name}", value, f"at most {most:g} {unit}")
        if self.lift_height / self.lift_speed > PHASE_MAX:
            raise ConfigError(
                "PhysicsOptions.lift_speed",
                self.lift_speed,
                f"a lift of at most {PHASE_MAX:g} s (lift_height / lift_speed)",
            )
        if self.neighbour_tipped_angle > math.pi:
            raise ConfigError(
                "PhysicsOptions.neighbour_tipped_angle",
                self.neighbour_tipped_angle,
                "an angle in (0, pi] rad",
            )
        if self.speed > 1:
            raise ConfigError("PhysicsOptions.speed", self.speed, "a fraction in (0, 1]")
        if self.lifted_fraction > 1:
            raise ConfigError(
                "PhysicsOptions.lifted_fraction", self.lifted_fraction, "a fraction in (0, 1]"
            )
