"""URDF and SRDF handling: building Pinocchio models, composing an arm and a hand into
one merged URDF (written to a content-hashed cache), reading ``<mimic>`` tags.
"""

from __future__ import annotations

import contextlib
import hashlib
import math
import os
import sys
import tempfile
import warnings
import xml.etree.ElementTree as ET
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TypeVar

import coal
import numpy as np
import pinocchio as pin

from openup_ompl._io import write_atomic
from openup_ompl._model import frame_id
from openup_ompl.exceptions import ConfigError
from openup_ompl.robot_file import MimicSpec, MountSpec, RobotSpec

T = TypeVar("T")

#: Thinnest spread of a mesh's vertices, as a fraction of their widest, that is hulled
#: (:func:`_check_hull_points`; singular values of the centred vertices): Coal's
#: ``buildConvexHull`` crashed on 20 random points 3e-8 of their width thick, and hulled
#: them at 1e-7.
FLAT_TOLERANCE = 1e-6

#: Size attributes of the URDF collision primitives: each must be positive and finite.
_PRIMITIVE_SIZES = {
    "box": ("size",),
    "cylinder": ("radius", "length"),
    "sphere": ("radius",),
    "capsule": ("radius", "length"),
}


def cache_dir() -> Path:
    """Where the loader writes merged URDFs: ``$OPENUP_OMPL_CACHE``, else
    ``$XDG_CACHE_HOME/openup-ompl``, else ``~/.cache/openup-ompl``.

    Returns:
        The directory (not created here).
    """
    if os.environ.get("OPENUP_OMPL_CACHE"):
        return Path(os.environ["OPENUP_OMPL_CACHE"]).expanduser()
    root = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(root).expanduser() / "openup-ompl"


def _write_cached(text: str, stem: str, suffix: str) -> Path:
    """Write ``text`` to the cache under a content-hashed name (atomic, reused)."""
    digest = hashlib.sha256(text.encode()).hexdigest()[:16]
    path = cache_dir() / f"{stem}-{digest}{suffix}"
    if not path.is_file():
        write_atomic(path, text)
    return path


def urdf_tree(path: Path, where: str, kind: str = "URDF") -> ET.Element:
    """The root ``<robot>`` element of a URDF or SRDF (``kind``), parsed here first so
    that a file that is not XML is one :class:`ConfigError` instead of urdfdom's C++
    errors on stderr.

    Args:
        path: The file.
        where: How to name it in an error.
        kind: ``"URDF"`` or ``"SRDF"``, for the message.

    Returns:
        The parsed root element.
    """
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as error:
        raise ConfigError(where, str(path), f"a readable {kind} ({error})") from None
    if root.tag != "robot":
        raise ConfigError(
            where, str(path), f"{kind} XML with a <robot> root element, not <{root.tag}>"
        )
    return root


def check_urdf_values(root: ET.Element, urdf: Path, where: str) -> None:
    """Refuse values urdfdom accepts but that make the model silently wrong: a revolute
    or prismatic joint whose ``<limit>`` has ``lower > upper`` (no configuration is within
    it), a collision primitive of a size that is not positive and finite (Coal builds it,
    and it never collides), and a collision mesh scale of zero or not finite (negative
    factors mirror the mesh, as example-robot-data's TIAGo does, and are kept).

    Args:
        root: The URDF's ``<robot>`` element.
        urdf: Its file, named in the message.
        where: The robot file and key that named it (e.g. ``"robot.toml: urdf"``).

    Raises:
        ConfigError: Naming the URDF file, the joint or link, and the bad value.
    """
    for joint in root.findall("joint"):
        limit = joint.find("limit")
        if joint.get("type") not in ("revolute", "prismatic") or limit is None:
            continue
        lower, upper = (_number(limit.get(key, "0")) for key in ("lower", "upper"))
        if lower > upper:
            raise ConfigError(
                f"{where} {urdf}: joint {joint.get('name')} <limit>",
                {"lower": lower, "upper": upper},
                "lower <= upper",
            )
    for link in root.findall("link"):
        for shape in link.findall("collision/geometry/*"):
            keys = ("scale",) if shape.tag == "mesh" else _PRIMITIVE_SIZES.get(shape.tag, ())
            for key in keys:
                text = shape.get(key)
                if text is None:
                    continue
                values = [_number(word) for word in text.split()]
                finite = bool(values) and all(math.isfinite(x) for x in values)
                if shape.tag == "mesh":
                    ok = finite and all(x != 0 for x in values)
                    expected = "non-zero finite scale factors"
                else:
                    ok = finite and all(x > 0 for x in values)
                    expected = "a positive finite size [m]"
                if not ok:
                    raise ConfigError(
                        f"{where} {urdf}: link {link.get('name')}: <collision> <{shape.tag} {key}>",
                        values[0] if len(values) == 1 else (values or text),
                        expected,
                    )


def _number(text: str) -> float:
    """A number of a URDF attribute, NaN if it is not one (urdfdom refuses it later)."""
    try:
        return float(text)
    except ValueError:
        return math.nan


def urdf_mimic(root: ET.Element) -> tuple[MimicSpec, ...]:
    """The ``<mimic>`` tags of a URDF, as follower specs.

    Args:
        root: A URDF's root element.

    Returns:
        One follower spec per ``<mimic>`` joint (leader, multiplier, offset [rad or m]).
    """
    specs = []
    for joint in root.iter("joint"):
        tag = joint.find("mimic")
        if tag is not None and joint.get("name") and tag.get("joint"):
            specs.append(
                MimicSpec(
                    joint=str(joint.get("name")),
                    leader=str(tag.get("joint")),
                    multiplier=float(tag.get("multiplier", 1.0)),
                    offset=float(tag.get("offset", 0.0)),
                )
            )
    return tuple(specs)


def _resolve_chains(mimic: tuple[MimicSpec, ...], driven: tuple[str, ...]) -> tuple[MimicSpec, ...]:
    """URDF followers whose leader chain ends at a driven joint, composed to that joint."""
    by_joint = {m.joint: m for m in mimic}
    resolved = []
    for spec in mimic:
        leader, mult, off, seen = spec.leader, spec.multiplier, spec.offset, {spec.joint}
        while leader not in driven and leader in by_joint and leader not in seen:
            seen.add(leader)
            up = by_joint[leader]
            leader, mult, off = up.leader, mult * up.multiplier, mult * up.offset + off
        if leader in driven:
            resolved.append(MimicSpec(spec.joint, leader, mult, off))
    return tuple(resolved)


def absolute_meshes(root: ET.Element, urdf: Path, package_dirs: list[str]) -> None:
    """Rewrite ``package://`` and relative mesh file names as absolute paths.

    Args:
        root: A URDF's root element, changed in place.
        urdf: The URDF file (for relative names).
        package_dirs: Directories ``package://`` names are looked up in.
    """
    for mesh in root.iter("mesh"):
        name = mesh.get("filename", "")
        if name.startswith("package://"):
            rest = name[len("package://") :]
            for base in package_dirs:
                if (Path(base) / rest).is_file():
                    mesh.set("filename", str((Path(base) / rest).resolve()))
                    break
        elif name.startswith("file://"):
            mesh.set("filename", name[len("file://") :])
        elif name and not Path(name).is_absolute():
            mesh.set("filename", str((urdf.parent / name).resolve()))


def _prefix_names(root: ET.Element, prefix: str) -> None:
    """Prefix every link and joint name (and the references to them) of a URDF or SRDF."""
    if not prefix:
        return
    for element in root.iter():
        if element.tag in ("link", "joint") and element.get("name"):
            element.set("name", prefix + str(element.get("name")))
        if element.tag in ("parent", "child") and element.get("link"):
            element.set("link", prefix + str(element.get("link")))
        if element.tag == "mimic" and element.get("joint"):
            element.set("joint", prefix + str(element.get("joint")))
        if element.tag == "disable_collisions":
            for key in ("link1", "link2"):
                element.set(key, prefix + str(element.get(key)))


def _root_link(root: ET.Element) -> str:
    children = {c.get("link") for c in root.iter("child")}
    links = [
        str(link.get("name")) for link in root.findall("link") if link.get("name") not in children
    ]
    return links[0]


def _merged_urdf(
    spec: RobotSpec,
    mount: MountSpec,
    arm_model: pin.Model,
    package_dirs: list[str],
    arm: ET.Element,
) -> tuple[Path, Path, Path | None]:
    """Write the merged URDF (and the prefixed hand URDF/SRDF) to the cache; ``arm`` is
    the arm URDF's root element (:func:`_build`'s, changed here).

    Returns:
        The merged URDF, the hand URDF to load, the hand SRDF to apply.
    """
    where = f"{spec.path.name}: mount"
    hand = urdf_tree(mount.urdf, f"{where}.urdf")
    check_urdf_values(hand, mount.urdf, f"{where}.urdf")
    _prefix_names(hand, mount.prefix)
    hand_urdf, hand_srdf = mount.urdf, mount.srdf
    if mount.prefix:
        hand_abs = ET.fromstring(ET.tostring(hand))
        absolute_meshes(hand_abs, mount.urdf, [*package_dirs, str(mount.urdf.parent)])
        hand_urdf = _write_cached(ET.tostring(hand_abs, encoding="unicode"), "hand", ".urdf")
        if mount.srdf is not None:
            srdf = urdf_tree(mount.srdf, f"{where}.srdf", "SRDF")
            _prefix_names(srdf, mount.prefix)
            hand_srdf = _write_cached(ET.tostring(srdf, encoding="unicode"), "hand", ".srdf")
    absolute_meshes(arm, spec.urdf, package_dirs)
    absolute_meshes(hand, mount.urdf, [*package_dirs, str(mount.urdf.parent)])
    arm_names = {e.get("name") for e in arm if e.tag in ("link", "joint")}
    clash = sorted(
        str(e.get("name"))
        for e in hand
        if e.tag in ("link", "joint") and e.get("name") in arm_names
    )
    if clash:
        raise ConfigError(f"{where}.prefix", mount.prefix, f"a prefix making {clash[0]!r} unique")
    # The link the hand is fixed to: the frame itself if a link, else a joint's child link.
    parent_frame = arm_model.frames[frame_id(arm_model, mount.frame)]
    links = {e.get("name") for e in arm.findall("link")}
    if mount.frame in links:
        parent_link = mount.frame
    else:
        joint = next(j for j in arm.findall("joint") if j.get("name") == parent_frame.name)
        parent_link = str(joint.find("child").get("link"))  # type: ignore[union-attr]
    placement = pin.XYZQUATToSE3(mount.pose)
    rpy = pin.rpy.matrixToRpy(placement.rotation)
    fixed = ET.SubElement(arm, "joint", {"name": f"{mount.prefix}openup_mount", "type": "fixed"})
    ET.SubElement(fixed, "parent", {"link": parent_link})
    ET.SubElement(fixed, "child", {"link": _root_link(hand)})
    ET.SubElement(
        fixed,
        "origin",
        {
            "xyz": " ".join(repr(float(x)) for x in placement.translation),
            "rpy": " ".join(repr(float(x)) for x in rpy),
        },
    )
    materials = {e.get("name") for e in arm.findall("material")}
    for element in hand:
        if element.tag in ("link", "joint") or (
            element.tag == "material" and element.get("name") not in materials
        ):
            arm.append(element)
    arm.set("name", spec.name)
    merged = _write_cached(ET.tostring(arm, encoding="unicode"), spec.name, ".urdf")
    return merged, hand_urdf, hand_srdf


def _build(
    urdf: Path, package_dirs: list[str], where: str
) -> tuple[pin.Model, pin.GeometryModel, ET.Element]:
    """The model and collision model of a URDF, and its root element: parsed here first,
    so that a file that is not URDF XML is one :class:`ConfigError` (see
    :func:`urdf_tree`)."""
    root = urdf_tree(urdf, where)
    check_urdf_values(root, urdf, where)

    def build() -> tuple[pin.Model, pin.GeometryModel]:
        model = pin.buildModelFromUrdf(str(urdf))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            collision = pin.buildGeomFromUrdf(
                model, str(urdf), pin.COLLISION, package_dirs=package_dirs
            )
        return model, collision

    model, collision = parsed_by_pinocchio(urdf, where, build)
    return model, collision, root


def urdf_model(urdf: str | Path, where: str) -> pin.Model:
    """Pinocchio's kinematic model of the URDF file ``urdf``.

    Args:
        urdf: The URDF file.
        where: How to name it in an error.

    Returns:
        The model.

    Raises:
        ConfigError: Pinocchio cannot load it, with urdfdom's reasons (named at ``where``).
    """
    return parsed_by_pinocchio(urdf, where, lambda: pin.buildModelFromUrdf(str(urdf)))


def parsed_by_pinocchio(urdf: str | Path, where: str, build: Callable[[], T]) -> T:
    """``build()``, a Pinocchio parse of the URDF file ``urdf``, with urdfdom's lines kept
    off the terminal: a file urdfdom refuses is one :class:`ConfigError` (named at
    ``where``) that carries its reasons ("Joint [j] ... does not specify limits"), without
    their source-line trailers; a loaded file's warnings still reach stderr.

    Args:
        urdf: The URDF file being parsed.
        where: How to name it in an error.
        build: The parse to run.

    Returns:
        What ``build`` returns.
    """
    try:
        with _native_stderr() as printed:
            result = build()
    except (RuntimeError, ValueError) as error:
        # The block has ended: ``printed`` holds urdfdom's lines.
        reasons = [line.removeprefix("Error:").strip() for line in printed if "Error:" in line]
        because = str(error).strip() + (f" urdfdom: {'; '.join(reasons)}" if reasons else "")
        raise ConfigError(where, str(urdf), f"a loadable URDF ({because})") from None
    for line in printed:
        print(line, file=sys.stderr)
    return result


@contextlib.contextmanager
def _native_stderr() -> Iterator[list[str]]:
    """Collect what native code writes to file descriptor 2 meanwhile (urdfdom prints its
    parse errors there, two lines each), as the lines of the list yielded once the block
    ends, instead of letting it reach the terminal beside the library's own message."""
    lines: list[str] = []
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as sink:
        os.dup2(sink.fileno(), 2)
        try:
            yield lines
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            sink.seek(0)
            lines.extend(sink.read().decode(errors="replace").splitlines())


def _convex_hulls(model: pin.Model, geometry_model: pin.GeometryModel, where: str) -> None:
    """Replace every mesh by its convex hull (qhull): conservative, and faster to check.

    Raises:
        ConfigError: A mesh with no solid hull (:func:`_check_hull_points`), named with
            its link at ``where`` (the robot file).
    """
    for geometry in geometry_model.geometryObjects:
        shape = geometry.geometry
        if isinstance(shape, coal.BVHModelBase):
            _check_hull_points(
                shape.vertices(), model.frames[geometry.parentFrame].name, geometry.meshPath, where
            )
            shape.buildConvexHull(True, "Qt")
            geometry.geometry = shape.convex


def _check_hull_points(points: np.ndarray, link: str, mesh: str, where: str) -> None:
    """Refuse mesh vertices whose convex hull is no solid: fewer than 4 points, or all of
    them in one plane (or on one line) up to :data:`FLAT_TOLERANCE` of their spread. Coal
    raises a bare ``ValueError`` for the first and crashes the process (SIGSEGV, in qhull's
    error path) on the second.
    """
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    if len(points) < 4:
        shown: object = f"{len(points)} vertices"
    else:
        spread = np.linalg.svd(points - points.mean(axis=0), compute_uv=False)
        if spread[-1] > FLAT_TOLERANCE * spread[0]:
            return
        shown = f"{len(points)} vertices in one plane"
    raise ConfigError(
        f"{where}: link {link}: collision mesh {mesh}",
        shown,
        "at least 4 vertices not all in one plane, to replace the mesh by its convex hull"
        f" (or set convex = false in {where} to collide with the mesh itself)",
    )


def remove_srdf_pairs(
    model: pin.Model, collision: pin.GeometryModel, srdf: Path, where: str
) -> None:
    """Leave out of ``collision`` the pairs the SRDF disables.

    Args:
        model: The robot's Pinocchio model.
        collision: Its collision geometry model, changed in place.
        srdf: The SRDF file.
        where: How to name it in an error.

    Raises:
        ConfigError: The file is not an SRDF pinocchio can read (named at ``where``),
            instead of pinocchio's ``RuntimeError``.
    """
    urdf_tree(srdf, where, "SRDF")
    try:
        pin.removeCollisionPairs(model, collision, str(srdf))
    except (RuntimeError, ValueError) as error:
        raise ConfigError(where, str(srdf), f"a loadable SRDF ({error})") from None


def _merged_srdf(
    spec: RobotSpec, mount: MountSpec, hand_srdf: Path | None, pairs: list[tuple[str, str]]
) -> Path:
    """Write one SRDF holding the arm's and the hand's disabled pairs plus ``pairs``."""
    merged = ET.Element("robot", {"name": spec.name})
    for srdf, where in ((spec.srdf, "srdf"), (hand_srdf, "mount.srdf")):
        if srdf is not None:
            root = urdf_tree(srdf, f"{spec.path.name}: {where}", "SRDF")
            merged.extend(root.iter("disable_collisions"))
    for a, b in pairs:
        ET.SubElement(merged, "disable_collisions", {"link1": a, "link2": b, "reason": "Never"})
    return _write_cached(ET.tostring(merged, encoding="unicode"), spec.name, ".srdf")
