"""``openup-ompl execute PLAN.json``: run a plan in physics (MuJoCo), after re-validating
it against its scene (:func:`~openup_ompl.revalidate.revalidate_plan`)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from openup_ompl.cli._common import add_validate_option, dir_out, out_path, seed
from openup_ompl.exceptions import ConfigError

if TYPE_CHECKING:
    from openup_ompl.scene import Shape

HELP = (
    "run a plan in physics (MuJoCo): reach with the object free, close, lift 10 cm,"
    " hold; exit 0 held, 1 failed"
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The plan, the object's pose error (an offset, or a scene holding the true object),
    ``--out``, the seed and ``--no-validate``."""
    parser.add_argument("plan", type=Path, help="plan JSON (see the docs' file formats)")
    truth = parser.add_mutually_exclusive_group()
    truth.add_argument(
        "--object-offset",
        type=float,
        nargs=3,
        default=(0.0, 0.0, 0.0),
        metavar=("DX", "DY", "YAW"),
        help="true object pose error: world x, y [m] and yaw about its own z [rad]",
    )
    truth.add_argument(
        "--true-scene",
        type=Path,
        default=None,
        metavar="SCENE",
        help="execute against the object where this scene file has it (a plan of"
        " perceive's perceived.toml against the original scene): the offset is the true"
        " object's planar pose relative to the plan's",
    )
    parser.add_argument(
        "--out", type=out_path, default=None, help="output directory (default: the plan's)"
    )
    parser.add_argument(
        "--seed", type=seed, default=1, help="run seed (draws PhysicsOptions.object_jitter)"
    )
    add_validate_option(parser)


def run(args: argparse.Namespace) -> int:
    """Read and re-validate the plan, execute it, write ``execution.json``. Returns 0
    on a held grasp, 1 on a failed one.

    Raises:
        ConfigError: A bad plan, offset, ``--true-scene`` or ``--out``.
        PlanRejected: The plan fails its re-validation.
    """
    from openup_ompl.physics import execute_plan, write_execution
    from openup_ompl.physics.rollout import check_offset
    from openup_ompl.plan import PlanFile
    from openup_ompl.revalidate import revalidate_plan

    if args.out is not None:
        dir_out(args.out)
    check_offset(args.object_offset)
    plan = PlanFile.read(args.plan)
    if plan.object is None:
        raise ConfigError(f"{args.plan.name}: scene.object", None, "an object to grasp")
    offset = args.object_offset
    if args.true_scene is not None:
        offset = true_offset(plan.object, args.true_scene)
    if not args.no_validate:
        revalidate_plan(plan, where=f"{args.plan.name}: ")
    record = execute_plan(plan, offset, seed=args.seed)
    path = write_execution(record, args.out if args.out is not None else args.plan.parent)
    print(f"{record.verdict} (execution written to {path})")
    return 0 if record.success else 1


def true_offset(planned: Shape, scene: Path) -> tuple[float, float, float]:
    """The offset that executes a plan against the object of another scene file.

    Args:
        planned: The object as the plan has it (a perceived plan: the estimate).
        scene: A scene file holding the same object where it truly is.

    Returns:
        ``(dx [m], dy [m], yaw [rad])``: the true object's planar pose relative to the
        planned one (:func:`~openup_ompl.perception.closed_loop.planar_offset`; height and
        tilt are the plan's).

    Raises:
        ConfigError: The scene has no object, another object (name or shape), or one
            beyond the offsets a rollout accepts (1 m, a yaw in [-pi, pi]).
    """
    from openup_ompl.perception.closed_loop import planar_offset
    from openup_ompl.physics.rollout import check_offset
    from openup_ompl.scene import load_scene

    true = load_scene(scene).object
    if true is None:
        raise ConfigError(f"{scene.name}: object", None, "the object the plan grasps")
    if (true.name, true.shape) != (planned.name, planned.shape):
        raise ConfigError(
            f"{scene.name}: object",
            f"{true.name} ({true.shape})",
            f"the plan's object, {planned.name} ({planned.shape})",
        )
    offset = planar_offset(planned, true)
    check_offset(offset)
    return offset
