"""Contact sensors that tell the simulation loop, per step, whether MuJoCo's contact list
holds anything it must read one contact at a time (:class:`Watch`).

MuJoCo's ``contact`` sensors (computed inside ``mj_step``, from the same contacts) give:
the object against the fixed obstacles (how many contacts, the deepest one's distance),
each moving part of the robot against the object (the same), and each moving part of the
robot against the fixed obstacles and against each neighbour (how many contacts). A step
whose contacts are only the object on its support and the hand on the object (once its
first touch is recorded) is then read from a few numbers; the rest go through the contact
list as before (:meth:`~openup_ompl.physics.monitor.Monitor.step`). Sensors do not change
the simulation: the trajectory is the same to the last bit. (MuJoCo 3.3.6 or later: a
``subtree`` of any body, not only of the world's children.)
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import mujoco

__all__ = ["WATCH", "Watch", "add_watch", "watch_of"]

#: Name prefix of the watch's sensors (``"watch:<what>:<robot body>[:<neighbour>]"``).
WATCH = "watch:"


@dataclass(frozen=True)
class Watch:
    """Where the watch's sensors sit in ``mjData.sensordata``.

    Attributes:
        pressed: Index of the number of object-obstacle contacts (their least distance
            [m] at ``pressed + 1``).
        gripped: Index of the number of contacts of each moving robot part with the
            object (their least distance [m] at the next index).
        touching: Index of the number of contacts of each moving robot part with the
            fixed obstacles and with each neighbour.
    """

    pressed: int
    gripped: tuple[int, ...]
    touching: tuple[int, ...]


def _moving_roots(spec: mujoco.MjSpec, free_bodies: set[str]) -> list[str]:
    """The robot bodies that move while no body above them does (the roots of the
    subtrees whose geoms are the robot's moving ones)."""
    jointed = {joint.parent.name for joint in spec.joints} - free_bodies
    roots = []
    for body in spec.bodies:
        if body.name not in jointed:
            continue
        parent = body.parent
        while parent is not None and parent.name != "world" and parent.name not in jointed:
            parent = parent.parent
        if parent is None or parent.name == "world":
            roots.append(body.name)
    return roots


def add_watch(spec: mujoco.MjSpec, object_body: str, neighbour_bodies: Sequence[str]) -> None:
    """Add the watch's contact sensors to ``spec`` (before it is compiled).

    Args:
        spec: The world's spec: robot, object and neighbours added, changed in place.
        object_body: The object's body name.
        neighbour_bodies: The neighbours' body names.
    """
    import mujoco

    fields = mujoco.mjtConDataField
    found, dist = int(fields.mjCONDATA_FOUND), int(fields.mjCONDATA_DIST)
    found_dist, found_only = (1 << found) | (1 << dist), 1 << found
    mindist = 1  # MuJoCo's reduce="mindist": the contact of least distance first
    body, subtree = mujoco.mjtObj.mjOBJ_BODY, mujoco.mjtObj.mjOBJ_XBODY

    def sensor(name: str, objtype: Any, obj: str, ref: str, data: int) -> None:
        spec.add_sensor(
            name=WATCH + name, type=mujoco.mjtSensor.mjSENS_CONTACT, objtype=objtype,
            objname=obj, reftype=body, refname=ref, intprm=[data, mindist, 1],
        )  # fmt: skip

    sensor("pressed", body, object_body, "world", found_dist)
    for root in _moving_roots(spec, {object_body, *neighbour_bodies}):
        sensor(f"gripped:{root}", subtree, root, object_body, found_dist)
        sensor(f"hit:{root}", subtree, root, "world", found_only)
        for other in neighbour_bodies:
            sensor(f"nudged:{root}:{other}", subtree, root, other, found_only)


def watch_of(model: Any) -> Watch:
    """The sensor indices of a compiled world's watch (:func:`add_watch`).

    Args:
        model: The compiled ``mujoco.MjModel``.

    Returns:
        Where each sensor's values start in ``sensordata``.
    """
    address = {model.sensor(i).name: int(model.sensor_adr[i]) for i in range(model.nsensor)}
    named = [(name[len(WATCH) :], a) for name, a in address.items() if name.startswith(WATCH)]
    return Watch(
        pressed=address[WATCH + "pressed"],
        gripped=tuple(a for name, a in named if name.startswith("gripped:")),
        touching=tuple(a for name, a in named if name.startswith(("hit:", "nudged:"))),
    )
