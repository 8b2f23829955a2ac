"""The phases of a rollout, in order: settle, reach, close, squeeze, lift, hold.

Each phase drives the :class:`~openup_ompl.physics.monitor.Monitor`'s actuator targets
for its stretch of simulated time and returns that duration [s]; the reach and the lift
keep their own tracking errors.
"""

from __future__ import annotations

import math

import numpy as np

from openup_ompl.physics.monitor import Monitor
from openup_ompl.physics.trajectory import Timed, sample
from openup_ompl.physics.world import World

__all__ = [
    "PHASE_ORDER", "Closing", "Lift", "LiftTargets", "Reach", "ReachTargets", "hold", "settle",
]  # fmt: skip

#: The phases' names, in order.
PHASE_ORDER = ("settle", "reach", "close", "squeeze", "lift", "hold")
#: Time [s] the reach holds the plan's last row after the timed path ends.
REACH_TAIL = 0.1


def settle(monitor: Monitor, seconds: float) -> float:
    """The object rests where it really is, the robot at the plan's first row.

    Args:
        monitor: The rollout's monitor.
        seconds: Nominal duration [s] of simulated time.

    Returns:
        The phase's duration [s]: ``seconds``, or less if the rollout ended in it.
    """
    return _wait(monitor, "settle", seconds)


def _wait(monitor: Monitor, phase: str, seconds: float) -> float:
    """Run ``phase`` for ``seconds`` [s] with the targets as they are; its duration [s]."""
    monitor.phase, monitor.phase_start = phase, monitor.steps
    monitor.run_for(seconds)
    return _duration(monitor, seconds, round(seconds / monitor.dt))


def _duration(monitor: Monitor, nominal: float, steps: int) -> float:
    """A phase's duration [s]: ``nominal``, or the time it ran if the rollout ended in it."""
    if monitor.ended is None or monitor.ended["phase"] != monitor.phase:
        return nominal
    return (
        min(steps, round(monitor.ended["time_s"] / monitor.dt) - monitor.phase_start) * monitor.dt
    )


class ReachTargets:
    """The reach's actuator targets, the same for every trial of a plan: the timed path
    at each step and the commands with velocity feed-forward,
    ``kp (q* + kv/kp v* - q) - kv v = kp (q* - q) + kv (v* - v)`` (no lag of ``kv v / kp``
    behind a moving target).

    Args:
        timed: The timed path.
        lead: ``kv / kp`` of each joint's actuator [s].
        dt: The timestep [s].
    """

    def __init__(self, timed: Timed, lead: np.ndarray, dt: float) -> None:
        self.steps = math.ceil(timed.duration / dt) + round(REACH_TAIL / dt)
        # The path at (k + 1) dt, k = 0 .. steps: step k's target and the next one.
        self.targets = sample(timed, np.arange(1, self.steps + 2) * dt)
        ahead, desired = self.targets[1:], self.targets[:-1]
        self.commands = (ahead - desired) * (lead / dt) + desired


class Reach:
    """The plan's rows as timed (:func:`~openup_ompl.physics.trajectory.time_path`).

    Attributes:
        arm_error: Largest arm tracking error [rad or m].
        hand_error: Largest hand tracking error before the hand touched the object.
    """

    def __init__(self, targets: ReachTargets) -> None:
        self.plan = targets
        self.arm_error = 0.0
        self.hand_error = 0.0

    def run(self, monitor: Monitor) -> float:
        """Drive the targets along the timed path.

        Args:
            monitor: The rollout's monitor.

        Returns:
            The phase's duration [s] (shorter if the rollout ended in it).
        """
        monitor.phase, monitor.phase_start = "reach", monitor.steps
        world, ctrl, plan = monitor.world, monitor.ctrl, self.plan
        log = np.empty((plan.steps, monitor.sim.qpos.size))
        done = monitor.drive(plan.commands[: plan.steps], log)
        if done:
            error = np.abs(log[:done, world.qpos] - plan.targets[:done])
            self.arm_error = max(0.0, float(error[:, world.arm].max()))
            if world.hand.size:
                # Steps after which the hand had not yet touched the object.
                touch = monitor.touch_step
                free = done if touch is None else max(0, min(done, touch - monitor.phase_start - 1))
                if free:
                    self.hand_error = max(0.0, float(error[:free, world.hand].max()))
            ctrl[:] = plan.targets[done - 1]
        return _duration(monitor, plan.steps * monitor.dt, plan.steps)


class Closing:
    """The hand's targets move from where the reach left them towards ``closed`` at
    ``rates`` [rad/s or m/s] (:meth:`close`), then stay there while each joint presses
    with its force limit (:meth:`squeeze`). Mimic followers follow their leaders.

    Args:
        world: The physics world.
        start: The hand's targets at the end of the reach.
        closed: The closed configuration of each hand joint.
        rates: Speed of each hand joint's target [rad/s or m/s].
    """

    def __init__(
        self, world: World, start: np.ndarray, closed: np.ndarray, rates: np.ndarray
    ) -> None:
        self.world = world
        self.start = start.copy()
        self.rates = rates
        self.span = np.abs(closed - self.start)
        self.direction = np.sign(closed - self.start)
        self.duration = float(np.max(self.span / rates)) if world.hand.size else 0.0

    def _targets(self, ctrl: np.ndarray, travel: np.ndarray) -> None:
        """Set the hand's targets in ``ctrl`` (a row, or one row per step) at ``travel``."""
        ctrl[..., self.world.hand] = self.start + self.direction * travel
        for follower, leader, multiplier, off in self.world.mimic:
            ctrl[..., follower] = multiplier * ctrl[..., leader] + off

    def close(self, monitor: Monitor) -> float:
        """Move the targets to the closed configuration.

        Args:
            monitor: The rollout's monitor.

        Returns:
            The phase's duration [s] (shorter if the rollout ended in it).
        """
        monitor.phase, monitor.phase_start = "close", monitor.steps
        rows = self.rows(monitor.ctrl, monitor.dt)
        monitor.drive(rows)
        return _duration(monitor, len(rows) * monitor.dt, len(rows))

    def rows(self, ctrl: np.ndarray, dt: float) -> np.ndarray:
        """The closing's targets, one row per step.

        Args:
            ctrl: The targets at its start (plan joint order).
            dt: The timestep [s].

        Returns:
            ``ctrl`` with the hand's targets moving, shape ``(steps, len(ctrl))``.
        """
        steps = math.ceil(self.duration / dt)
        # Step k's travel, min(span, rates (k + 1) dt), for every k at once.
        k = np.arange(1, steps + 1, dtype=float)[:, None]
        rows = np.tile(ctrl, (steps, 1))
        self._targets(rows, np.minimum(self.span, self.rates * k * dt))
        return rows

    def squeeze(self, monitor: Monitor, seconds: float) -> float:
        """Hold the closed targets: each joint presses on what stopped it.

        Args:
            monitor: The rollout's monitor.
            seconds: Nominal duration [s] of simulated time.

        Returns:
            The phase's duration [s]: ``seconds``, or less if the rollout ended in it.
        """
        monitor.phase, monitor.phase_start = "squeeze", monitor.steps
        steps = round(seconds / monitor.dt)
        if steps and monitor.ended is None:
            self._targets(monitor.ctrl, self.span)
            monitor.run_for(seconds)
        return _duration(monitor, steps * monitor.dt, steps)


class LiftTargets:
    """The lift's arm targets, the same for every trial of a plan: the IK rows (equal palm
    rises) at a smoothstep in time, starting and stopping at rest, and the commands with
    velocity feed-forward.

    Args:
        rows: The lift's configurations (:func:`~openup_ompl.physics.targets.lift_rows`).
        arm: Indices of the arm joints.
        lead: ``kv / kp`` of the arm joints' actuators [s].
        steps: Simulation steps of the lift.
        dt: The timestep [s].
    """

    def __init__(
        self, rows: np.ndarray, arm: np.ndarray, lead: np.ndarray, steps: int, dt: float
    ) -> None:
        self.rows, self.arm, self.steps = rows, arm, steps
        at = np.array([self.at(k) for k in range(steps + 2)])
        self.targets = at[1:-1]  # step k's target: at(k + 1)
        following = at[2:]
        self.commands = self.targets + lead * (following - self.targets) / dt
        self.top = at[steps]

    def at(self, k: int) -> np.ndarray:
        """Arm target at lift step ``k``.

        Args:
            k: The step (``0`` the start, ``steps`` the top; clamped beyond).

        Returns:
            The arm joints' target [rad or m], shape ``(len(arm),)``.
        """
        last = len(self.rows) - 1
        s = min(1.0, k / self.steps)
        x = s * s * (3 - 2 * s) * last
        i = min(int(x), max(last - 1, 0))
        a = min(1.0, x - i)
        j = min(i + 1, last)
        return self.rows[i, self.arm] + a * (self.rows[j, self.arm] - self.rows[i, self.arm])


class Lift:
    """The palm straight up (:class:`LiftTargets`), the hand's targets held.

    Attributes:
        arm_error: Largest arm tracking error [rad or m].
    """

    def __init__(self, targets: LiftTargets) -> None:
        self.plan = targets
        self.arm_error = 0.0

    def run(self, monitor: Monitor) -> float:
        """Drive the arm up; the targets end at the top.

        Args:
            monitor: The rollout's monitor.

        Returns:
            The phase's duration [s] (shorter if the rollout ended in it).
        """
        monitor.phase, monitor.phase_start = "lift", monitor.steps
        world, ctrl, plan = monitor.world, monitor.ctrl, self.plan
        rows = np.tile(ctrl, (plan.steps, 1))
        rows[:, plan.arm] = plan.commands
        log = np.empty((plan.steps, monitor.sim.qpos.size))
        done = monitor.drive(rows, log)
        if done:
            error = np.abs(log[:done, world.qpos[plan.arm]] - plan.targets[:done])
            self.arm_error = max(0.0, float(error.max()))
        ctrl[plan.arm] = plan.top
        return _duration(monitor, plan.steps * monitor.dt, plan.steps)


def hold(monitor: Monitor, seconds: float) -> float:
    """The targets stay at the top.

    Args:
        monitor: The rollout's monitor.
        seconds: Nominal duration [s] of simulated time.

    Returns:
        The phase's duration [s]: ``seconds``, or less if the rollout ended in it.
    """
    return _wait(monitor, "hold", seconds)
