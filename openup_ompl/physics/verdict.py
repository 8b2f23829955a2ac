"""The verdict of a rollout: the failure cause that applies first, the line for people,
the contacts at the end, and how each neighbour was disturbed."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from openup_ompl.physics.monitor import Monitor
from openup_ompl.physics.options import PhysicsOptions
from openup_ompl.physics.world import NEIGHBOUR, OBJECT, OBSTACLE, ROBOT, World

__all__ = ["DROPPED_RISE", "Outcome", "disturbance", "final_contacts", "judge", "pose_change"]

#: An object whose highest rise over the lift and hold exceeds this [m] and that no link
#: touches at the end was ``dropped`` (it rose, then left the hand), else ``no contact``.
DROPPED_RISE = 0.01


def pose_change(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """Translation and rotation angle between two rigid transforms.

    Args:
        a, b: Homogeneous transforms, shape ``(4, 4)`` [m], in the same frame.

    Returns:
        ``(distance [m], angle [rad])`` of ``a^-1 b`` (angle in ``[0, pi]``).
    """
    delta = np.linalg.inv(a) @ b
    cos = (np.trace(delta[:3, :3]) - 1) / 2
    return float(np.linalg.norm(delta[:3, 3])), float(math.acos(min(1.0, max(-1.0, cos))))


def final_contacts(sim: Any, world: World) -> tuple[set[tuple[str, str]], bool]:
    """The contacts at the end as ``(link or object, other)`` name pairs (robot with the
    object, an obstacle or a neighbour; the object with an obstacle), and whether a robot
    link holds the object.

    Args:
        sim: The MuJoCo data (``mujoco.MjData``) at the end of the rollout.
        world: The physics world it simulates.

    Returns:
        ``(pairs, holding)``: the set of name pairs and whether a robot link touches the
        object.
    """
    kinds, links = world.geom_kind, world.geom_link
    final = set()
    holding = False
    for i in range(sim.ncon):
        g = sim.contact.geom[i]
        a, b = int(g[0]), int(g[1])
        if kinds[b] == ROBOT:
            a, b = b, a
        if kinds[a] == ROBOT and kinds[b] in (OBJECT, OBSTACLE, NEIGHBOUR):
            final.add((links[a], links[b]))
            holding |= kinds[b] == OBJECT
        elif {int(kinds[a]), int(kinds[b])} == {OBJECT, OBSTACLE}:
            first, second = (a, b) if kinds[a] == OBJECT else (b, a)
            final.add((links[first], links[second]))
    return final, holding


def disturbance(
    name: str,
    start: np.ndarray,
    end: np.ndarray,
    options: PhysicsOptions,
    touched: dict[str, Any] | None,
) -> dict[str, Any]:
    """How a neighbour moved between two world transforms: its displacement, the turn of
    its up axis (its own z) and the thresholds' verdicts.

    Args:
        name: The neighbour's name.
        start, end: Its world transforms, shape ``(4, 4)`` [m], before and after.
        options: The thresholds (``neighbour_moved_distance`` [m],
            ``neighbour_tipped_angle`` [rad]).
        touched: The robot's first contact with it, or ``None``.

    Returns:
        ``{"name", "moved_mm", "tilt_deg", "moved", "tipped", "touched"}`` (displacement
        [mm], tilt [deg], the two verdicts and ``touched``).
    """
    moved = float(np.linalg.norm(end[:3, 3] - start[:3, 3]))
    cos = float(np.dot(start[:3, 2], end[:3, 2]))
    tilt = math.acos(min(1.0, max(-1.0, cos)))
    return {
        "name": name,
        "moved_mm": moved * 1e3,
        "tilt_deg": math.degrees(tilt),
        "moved": moved > options.neighbour_moved_distance,
        "tipped": tilt > options.neighbour_tipped_angle,
        "touched": touched,
    }


@dataclass(frozen=True)
class Outcome:
    """What the end of a rollout shows.

    Attributes:
        object_rise: The object's rise over the lift and hold [m].
        peak_rise: Its highest rise over them [m].
        palm_rise: The palm's rise [m].
        drift_m: The object's motion in the palm frame over the lift and hold [m].
        drift_rad: Its rotation there [rad].
        holding: A robot link touches the object at the end.
    """

    object_rise: float
    peak_rise: float
    palm_rise: float
    drift_m: float
    drift_rad: float
    holding: bool


def judge(
    monitor: Monitor, outcome: Outcome, options: PhysicsOptions, name: str
) -> tuple[str | None, str]:
    """The failure cause that applies first and the verdict's line.

    Args:
        monitor: The rollout's monitor, at its end.
        outcome: What the end shows.
        options: The thresholds of success.
        name: The object's name.

    Returns:
        ``(cause, line)``: the cause (``None``: held; else ``"obstacle contact"``,
        ``"jammed"``, ``"fell"``, ``"dropped"``, ``"no contact"``, ``"not lifted"`` or
        ``"slipped"``) and the verdict for people.
    """
    obstacle_contacts = sorted(monitor.obstacles.values(), key=lambda c: c["time_s"])
    lifted = outcome.object_rise >= options.lifted_fraction * options.lift_height
    cause: str | None = None
    if obstacle_contacts:
        cause = "obstacle contact"
    elif monitor.pressed > options.max_penetration:
        cause = "jammed"
    elif monitor.sunk is not None:
        cause = "fell"
    elif not outcome.holding:
        cause = "dropped" if outcome.peak_rise > DROPPED_RISE else "no contact"
    elif not lifted:
        cause = "not lifted"
    elif outcome.drift_m > options.success_distance or outcome.drift_rad > options.success_angle:
        cause = "slipped"
    return cause, _line(cause, monitor, outcome, name, obstacle_contacts)


def _line(
    cause: str | None,
    monitor: Monitor,
    outcome: Outcome,
    name: str,
    obstacle_contacts: list[dict[str, Any]],
) -> str:
    """The verdict for people."""
    pressed_mm = monitor.pressed * 1e3
    if cause is None:
        return (
            f"held: {name} lifted {outcome.object_rise * 1e3:.0f} mm, moved"
            f" {outcome.drift_m * 1e3:.1f} mm / {math.degrees(outcome.drift_rad):.1f} deg in"
            " the hand over the hold"
        )
    if cause == "jammed" and monitor.pressed_phase == "settle":
        # Before the robot moves: the object was placed overlapping an obstacle (an
        # offset into a wall, say), not pushed there by the hand.
        return (
            f"failed (jammed): {name} lay {pressed_mm:.0f} mm inside an obstacle during the"
            " settle, before the robot moved (placed there)"
        )
    if cause == "jammed":
        return (
            f"failed (jammed): the hand forced {name} {pressed_mm:.0f} mm into an obstacle"
            f" during the {monitor.pressed_phase} (a real arm would stall; MuJoCo's soft"
            " contact gave way)"
        )
    if cause == "fell":
        return (
            f"failed (fell): {name} dropped below any pose resting on its support during"
            f" the {monitor.sunk} (off the table or through it)"
        )
    if cause == "obstacle contact":
        first = obstacle_contacts[0]
        return (
            f"failed (obstacle contact): {first['link']} hit {first['obstacle']} at"
            f" {first['time_s']:.2f} s ({first['phase']})"
        )
    return (
        f"failed ({cause}): {name} rose {outcome.object_rise * 1e3:.0f} mm of the palm's"
        f" {outcome.palm_rise * 1e3:.0f} mm, moved {outcome.drift_m * 1e3:.0f} mm /"
        f" {math.degrees(outcome.drift_rad):.0f} deg in the hand"
    )
