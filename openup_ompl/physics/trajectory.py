"""Timing of a plan: the path's rows as a function of time under the URDF velocity limits.

The profile: each segment between consecutive rows lasts as long as its slowest joint
needs at ``speed`` times its velocity limit (the rows are a few millimetres apart, so the
segments are short and the motion follows the planned path closely); the path parameter
then runs through a trapezoidal time warp, accelerating over ``ramp`` seconds from rest
and decelerating as long into rest at the grasp. Velocities are bounded by ``speed`` times
the limits; accelerations by roughly their ratio to ``ramp`` (no torque limits are taken
into account: the controller's force limits act instead).
"""

from __future__ import annotations

import numpy as np

__all__ = ["Timed", "time_path"]


class Timed:
    """A path with a time per row; :meth:`at` interpolates it linearly.

    Attributes:
        rows: ``(N, n)`` configurations.
        tau: ``(N,)`` row times at full speed [s] (before the ramp warp).
        duration: Total time [s], ramps included.
        ramp: Ramp duration [s] (``0`` when the path is too short for one).
    """

    def __init__(self, rows: np.ndarray, tau: np.ndarray, ramp: float) -> None:
        self.rows = np.asarray(rows, dtype=float)
        self.tau = np.asarray(tau, dtype=float)
        length = float(self.tau[-1])
        self.ramp = min(ramp, length)
        self.duration = length + self.ramp

    def _warp(self, t: float) -> float:
        """Path time ``tau`` at time ``t``: speed ramps 0 -> 1 -> 0 over ``ramp``."""
        r, total = self.ramp, self.duration
        t = min(max(t, 0.0), total)
        if r <= 0:
            return t
        if t < r:
            return t * t / (2 * r)
        if t > total - r:
            rest = total - t
            return total - r - rest * rest / (2 * r)
        return t - r / 2

    def at(self, t: float, out: np.ndarray | None = None) -> np.ndarray:
        """The configuration at time ``t`` [s] (held at the ends)."""
        tau = self._warp(t)
        i = int(np.searchsorted(self.tau, tau, side="right"))
        if i <= 0:
            q = self.rows[0]
        elif i >= len(self.tau):
            q = self.rows[-1]
        else:
            span = self.tau[i] - self.tau[i - 1]
            a = 0.0 if span <= 0 else (tau - self.tau[i - 1]) / span
            q = self.rows[i - 1] + a * (self.rows[i] - self.rows[i - 1])
        if out is None:
            return np.array(q)
        out[:] = q
        return out


def time_path(rows: np.ndarray, velocity_limit: np.ndarray, speed: float, ramp: float) -> Timed:
    """Time a path (module docstring).

    Args:
        rows: ``(N, n)`` configurations.
        velocity_limit: ``(n,)`` joint velocity limits [rad/s or m/s].
        speed: Fraction of the limits to move at, in (0, 1].
        ramp: Duration [s] of the acceleration from rest (and of the deceleration).
    """
    rows = np.asarray(rows, dtype=float)
    step = np.abs(np.diff(rows, axis=0)) / (speed * np.asarray(velocity_limit, dtype=float))
    durations = step.max(axis=1) if step.size else np.zeros(0)
    return Timed(rows, np.concatenate([[0.0], np.cumsum(durations)]), ramp)
