"""Timing of a plan: the path's rows as a function of time under velocity and acceleration
limits.

The path is the polyline through its rows (a few millimetres apart), parametrised by
``s`` (one unit per segment). Its speed ``sdot`` is the largest that keeps every joint

- under ``speed`` times its URDF velocity limit on each segment,
- under ``acceleration`` [rad/s^2 or m/s^2] along a segment, and at each row, where the
  polyline turns, under that acceleration over one segment's time (the turn's velocity
  change spread over it),

found by the usual forward and backward passes over the rows, from rest to rest (a
time-optimal profile for a path of straight segments with box limits, as in TOPP-RA but
without torque limits: the controller's force limits act instead). Within a segment the
speed changes at constant ``sddot``; positions interpolate the rows linearly in ``s``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["Timed", "sample", "time_path"]


class Timed:
    """A path with a time per row; :meth:`at` samples it.

    Attributes:
        rows: ``(N, n)`` configurations.
        times: ``(N,)`` time of each row [s].
        sdot: ``(N,)`` path speed at each row [segments/s].
        duration: Total time [s].
    """

    def __init__(self, rows: np.ndarray, times: np.ndarray, sdot: np.ndarray) -> None:
        self.rows = np.asarray(rows, dtype=float)
        self.times = np.asarray(times, dtype=float)
        self.sdot = np.asarray(sdot, dtype=float)
        self.duration = float(self.times[-1])

    def at(self, t: float, out: np.ndarray | None = None) -> np.ndarray:
        """The configuration at time ``t`` [s] (held at the ends).

        Args:
            t: Time from the start [s].
            out: An array to write into (``(n,)``), or ``None`` for a new one.

        Returns:
            The configuration ``(n,)`` [rad or m] at ``t``, interpolated between rows.
        """
        i = int(np.searchsorted(self.times, t, side="right"))
        if i <= 0:
            q = self.rows[0]
        elif i >= len(self.times):
            q = self.rows[-1]
        else:
            span = self.times[i] - self.times[i - 1]
            a, b = self.sdot[i - 1], self.sdot[i]
            tau = t - self.times[i - 1]
            # s within the segment at constant acceleration (b - a) / span.
            fraction = 0.0 if span <= 0 else a * tau + 0.5 * (b - a) / span * tau * tau
            q = self.rows[i - 1] + min(1.0, max(0.0, fraction)) * (self.rows[i] - self.rows[i - 1])
        if out is None:
            return np.array(q)
        out[:] = q
        return out


def sample(timed: Timed, times: np.ndarray) -> np.ndarray:
    """:meth:`Timed.at` at each of ``times`` [s], as rows (the same arithmetic, vectorised:
    the rows are equal to the last bit).

    Args:
        timed: The timed path.
        times: Times [s] from the path's start, shape ``(T,)``.

    Returns:
        Configurations [rad or m], shape ``(T, width)``; clamped to the first and last
        rows outside the path's span.
    """
    times = np.asarray(times, dtype=float)
    rows, knots, sdot = timed.rows, timed.times, timed.sdot
    i = np.searchsorted(knots, times, side="right")
    out = np.empty((times.size, rows.shape[1]))
    out[i <= 0] = rows[0]
    out[i >= len(knots)] = rows[-1]
    inside = (i > 0) & (i < len(knots))
    k, t = i[inside], times[inside]
    span = knots[k] - knots[k - 1]
    a, b = sdot[k - 1], sdot[k]
    tau = t - knots[k - 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        fraction = np.where(span <= 0, 0.0, a * tau + 0.5 * (b - a) / span * tau * tau)
    fraction = np.minimum(1.0, np.maximum(0.0, fraction))
    out[inside] = rows[k - 1] + fraction[:, None] * (rows[k] - rows[k - 1])
    return out


def time_path(
    rows: np.ndarray, velocity_limit: np.ndarray, speed: float, acceleration: float
) -> Timed:
    """Time a path from rest to rest (module docstring).

    Args:
        rows: ``(N, n)`` configurations.
        velocity_limit: ``(n,)`` joint velocity limits [rad/s or m/s].
        speed: Fraction of the velocity limits to move at, in (0, 1].
        acceleration: Joint acceleration limit [rad/s^2 or m/s^2].

    Returns:
        The timed path (:class:`Timed`): its rows' times [s] and interpolation.
    """
    rows = np.asarray(rows, dtype=float)
    n = len(rows)
    if n < 2:
        return Timed(rows, np.zeros(n), np.zeros(n))
    if n == 2:
        # Speeds are set at the rows, and a path from rest to rest is at rest at both of
        # its ends: one segment would never move (its time was 1e12 s). Its midpoint is
        # where it moves fastest.
        rows = np.array([rows[0], 0.5 * (rows[0] + rows[1]), rows[1]])
        n = 3
    step = np.diff(rows, axis=0)  # (N-1, n): joint motion per unit s
    size = np.abs(step)
    tiny = 1e-12
    segment_max = np.min(speed * np.asarray(velocity_limit) / np.maximum(size, tiny), axis=1)
    sddot_max = np.min(acceleration / np.maximum(size, tiny), axis=1)
    turn = np.abs(np.diff(step, axis=0))  # (N-2, n) velocity change per unit sdot
    node_max = np.full(n, np.inf)
    node_max[1:-1] = np.sqrt(np.min(acceleration / np.maximum(turn, tiny), axis=1))
    node_max[1:-1] = np.minimum(node_max[1:-1], np.minimum(segment_max[:-1], segment_max[1:]))
    node_max[0] = node_max[-1] = 0.0
    sdot = node_max.copy()
    for i in range(n - 1):  # forward: accelerate from rest
        sdot[i + 1] = min(sdot[i + 1], np.sqrt(sdot[i] ** 2 + 2 * sddot_max[i]))
    for i in range(n - 2, -1, -1):  # backward: decelerate to rest
        sdot[i] = min(sdot[i], np.sqrt(sdot[i + 1] ** 2 + 2 * sddot_max[i]))
    mean = np.maximum(0.5 * (sdot[:-1] + sdot[1:]), tiny)
    durations = np.where(size.max(axis=1) > tiny, 1.0 / mean, 0.0)
    return Timed(rows, np.concatenate([[0.0], np.cumsum(durations)]), sdot)
