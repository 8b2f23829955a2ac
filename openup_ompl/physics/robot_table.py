"""What the physics world needs of a robot (:class:`RobotTable`), from a plan file's
``robot`` table or a loaded robot, with its robot file's contact pads."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from openup_ompl.exceptions import OpenUpError

if TYPE_CHECKING:
    from openup_ompl.robot_file import PadSpec, RobotSpec

__all__ = ["RobotTable", "robot_spec"]


def robot_spec(name: str) -> RobotSpec | None:
    """The shipped or installed robot file of a robot.

    Args:
        name: The robot's name.

    Returns:
        Its robot file, read; ``None`` if none is found or it does not load.
    """
    from openup_ompl.robot_file import RobotSpec, find_robot_file

    try:
        return RobotSpec.from_file(find_robot_file(name))
    except OpenUpError:  # a robot this package does not know
        return None


@dataclass(frozen=True)
class RobotTable:
    """What the world needs of the robot: a plan file's ``robot`` table, typed.

    Attributes:
        name: The robot's name.
        urdf: Its URDF file.
        package_dirs: Directories resolving ``package://`` mesh URIs.
        palm_frame: The palm frame's link.
        joint_names: Every joint, in the order of a path row.
        arm_joints: The arm's joints.
        hand_joints: The hand's joints (driven, then followers).
        pads: Physics-only contact pads (its robot file's ``[physics] pads``).
    """

    name: str
    urdf: str
    package_dirs: tuple[str, ...]
    palm_frame: str
    joint_names: tuple[str, ...]
    arm_joints: tuple[str, ...]
    hand_joints: tuple[str, ...]
    pads: tuple[PadSpec, ...] = ()

    @classmethod
    def from_table(cls, table: dict[str, Any]) -> RobotTable:
        """A plan file's ``robot`` table (missing keys read as empty), with the pads of the
        robot file found by its name (none if no file is found).

        Args:
            table: The plan file's ``robot`` table.

        Returns:
            The table, typed (not checked: the world's build checks it).
        """
        spec = robot_spec(str(table.get("name")))
        return cls(
            name=str(table.get("name")),
            urdf=str(table.get("urdf") or ""),
            package_dirs=tuple(table.get("package_dirs") or ()),
            palm_frame=str(table.get("palm_frame")),
            joint_names=tuple(table.get("joint_names") or ()),
            arm_joints=tuple(table.get("arm_joints") or ()),
            hand_joints=tuple(table.get("hand_joints") or ()),
            pads=spec.pads if spec is not None else (),
        )

    @classmethod
    def from_robot(cls, robot: Any) -> RobotTable:
        """A loaded robot's table (what its plans' files hold).

        Args:
            robot: A loaded :class:`~openup_ompl.robot.Robot`.

        Returns:
            Its table.
        """
        return cls(
            name=robot.spec.name,
            urdf=str(robot.urdf),
            package_dirs=tuple(str(p) for p in robot.package_dirs),
            palm_frame=robot.spec.palm_frame,
            joint_names=tuple(robot.joint_names),
            arm_joints=tuple(robot.spec.arm_joints),
            hand_joints=tuple(robot.hand_joints),
            pads=tuple(robot.spec.pads),
        )
