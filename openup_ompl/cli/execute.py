"""``openup-ompl execute PLAN.json``: run a plan in physics (MuJoCo), after re-validating
it against its scene (:func:`~openup_ompl.revalidate.revalidate_plan`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from openup_ompl.cli._common import add_validate_option, dir_out, out_path, seed
from openup_ompl.exceptions import ConfigError

HELP = (
    "run a plan in physics (MuJoCo): reach with the object free, close, lift 10 cm,"
    " hold; exit 0 held, 1 failed"
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The plan, the object's error (an offset and/or the true scene), ``--out``, the
    seed and ``--no-validate``.

    Args:
        parser: The command's parser, given its options.
    """
    parser.add_argument("plan", type=Path, help="plan JSON (README, Files: Plan)")
    parser.add_argument(
        "--object-offset",
        type=float,
        nargs=3,
        default=(0.0, 0.0, 0.0),
        metavar=("DX", "DY", "YAW"),
        help="true object pose error: world x, y [m] and yaw about its own z [rad]",
    )
    parser.add_argument(
        "--truth",
        type=Path,
        default=None,
        metavar="SCENE.toml",
        help="the true scene: its [object] (pose, shape, mass, friction) replaces the plan's,"
        " e.g. the scene a perceived.toml was estimated from (--object-offset then moves it)",
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

    Args:
        args: The parsed command line.

    Returns:
        The exit status.

    Raises:
        ConfigError: A bad plan, offset, true scene or ``--out``.
        PlanRejected: The plan fails its re-validation.
    """
    from openup_ompl.physics import execute_plan, write_execution
    from openup_ompl.physics.rollout import check_offset
    from openup_ompl.plan import PlanFile
    from openup_ompl.revalidate import revalidate_plan
    from openup_ompl.scene import load_scene

    if args.out is not None:
        dir_out(args.out)
    check_offset(args.object_offset)
    truth = None if args.truth is None else load_scene(args.truth)
    plan = PlanFile.read(args.plan)
    if plan.object is None and truth is None:
        raise ConfigError(f"{args.plan.name}: scene.object", None, "an object to grasp")
    if not args.no_validate:  # against the plan's own scene: the true object may differ
        revalidate_plan(plan, where=f"{args.plan.name}: ")
    record = execute_plan(plan, args.object_offset, seed=args.seed, truth=truth)
    path = write_execution(record, args.out if args.out is not None else args.plan.parent)
    print(f"{record.verdict} (execution written to {path})")
    return 0 if record.success else 1
