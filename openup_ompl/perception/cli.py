"""``openup-ompl perceive``: one simulated view of a scene's object, fitted; writes the
cloud, the figure, ``perception.json`` and ``perceived.toml`` (ready for ``plan``)."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from openup_ompl import _toml
from openup_ompl.exceptions import ConfigError, MissingExtra
from openup_ompl.perception.camera import CameraOptions, camera_of_scene
from openup_ompl.scene import Problem, load_scene

__all__ = [
    "add_error_arguments",
    "camera_pairs",
    "closed_loop_command",
    "perceive_command",
    "perception_options",
    "scene_camera",
    "write_closed_loop",
]


def add_error_arguments(parser: argparse.ArgumentParser) -> None:
    """The camera's calibration errors and the estimator's restarts as options of a
    command (:class:`~openup_ompl.perception.extrinsic.PerceptionOptions`; its defaults).

    Args:
        parser: The command's parser, given ``--camera-position-sigma`` [m],
            ``--camera-angle-sigma`` [deg], ``--depth-bias-sigma`` [m] and ``--restarts``.
    """
    from openup_ompl.perception.extrinsic import PerceptionOptions

    default = PerceptionOptions()
    parser.add_argument(
        "--camera-position-sigma",
        type=float,
        default=default.camera_position_sigma,
        metavar="M",
        help="standard deviation [m] of the camera's believed position per axis"
        f" (default {default.camera_position_sigma:g}; 0: known exactly)",
    )
    parser.add_argument(
        "--camera-angle-sigma",
        type=float,
        default=default.camera_angle_sigma,
        metavar="DEG",
        help="standard deviation [deg] of the camera's believed orientation per axis"
        f" (default {default.camera_angle_sigma:g})",
    )
    parser.add_argument(
        "--depth-bias-sigma",
        type=float,
        default=default.depth_bias_sigma,
        metavar="M",
        help="standard deviation [m] of a depth offset common to a view's pixels"
        f" (default {default.depth_bias_sigma:g})",
    )
    parser.add_argument(
        "--restarts",
        type=int,
        default=default.restarts,
        metavar="N",
        help="fits per view: the points, then N-1 bootstrap resamples; u is their median"
        f" and their spread is reported (default {default.restarts})",
    )


def perception_options(args: argparse.Namespace) -> Any:
    """The perception options of parsed :func:`add_error_arguments` options.

    Args:
        args: The parsed command line.

    Returns:
        The :class:`~openup_ompl.perception.extrinsic.PerceptionOptions`.

    Raises:
        ConfigError: A bad value, naming it.
    """
    from openup_ompl.perception.extrinsic import PerceptionOptions

    return PerceptionOptions(
        camera_position_sigma=args.camera_position_sigma,
        camera_angle_sigma=args.camera_angle_sigma,
        depth_bias_sigma=args.depth_bias_sigma,
        restarts=args.restarts,
    )


def camera_pairs(pairs: Sequence[str]) -> dict[str, Any]:
    """``KEY=VALUE`` pairs (each VALUE a TOML value, e.g. ``distance=0.9``,
    ``position=[1, 0, 0.8]``) as a ``[camera]`` table.

    Args:
        pairs: The ``--camera`` arguments.

    Returns:
        Key -> parsed value.
    """
    table: dict[str, Any] = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        if not sep or not key.strip():
            raise ConfigError("--camera", pair, "KEY=VALUE, e.g. distance=0.9")
        try:
            table[key.strip()] = _toml.tomllib.loads(f"v = {value}")["v"]
        except _toml.tomllib.TOMLDecodeError:
            raise ConfigError(f"--camera {key.strip()}", value, "a TOML value") from None
    return table


def scene_camera(problem: Problem, pairs: Sequence[str]) -> CameraOptions:
    """The camera of a scene file's ``[camera]`` table, overridden by ``--camera``
    ``KEY=VALUE`` pairs.

    Args:
        problem: The scene (its ``[camera]`` table).
        pairs: The ``--camera`` arguments.

    Returns:
        The camera options, checked.
    """
    return camera_of_scene(problem, camera_pairs(pairs))


def perceive_command(args: argparse.Namespace) -> int:
    """``openup-ompl perceive``: look at the scene's object, fit it, write the outputs.

    Args:
        args: The parsed command line (``scene``, ``camera``, ``noise``, ``seed``, ``out``).

    Returns:
        0 (a view perception refuses raises instead).

    Raises:
        ConfigError: A bad scene or camera option.
        PerceptionError: The view cannot bound the object (not seen, too few points, cut
            off, occluded, a degenerate fit).
    """
    from openup_ompl.perception.noise import NoiseOptions
    from openup_ompl.perception.perceive import perceive, write_perception
    from openup_ompl.perception.viewpoint import choose_camera

    problem = load_scene(args.scene)
    pairs = args.camera or ["auto"]
    auto = pairs[0] == "auto"
    camera = scene_camera(problem, pairs[1:] if auto else pairs)
    noise = replace(NoiseOptions(), scale=args.noise)
    options = perception_options(args)
    depth_camera = None
    if auto:  # the configured view, else the best of a ring around the object
        choice = choose_camera(problem, camera)
        print(choice.describe())
        camera, depth_camera = choice.options, choice.camera
    perception = perceive(
        problem,
        camera,
        noise,
        rng=np.random.default_rng(args.seed),
        options=options,
        depth_camera=depth_camera,
    )
    paths = write_perception(problem, perception, args.out)
    assert problem.object is not None
    error = (perception.pose[:3] - problem.object.pose[:3]) * 1e3
    sigma = np.sqrt(np.diag(perception.position_covariance)) * 1e3
    print(
        f"{problem.object.name}: {perception.fit.points} object points"
        f" ({perception.cloud.dropped} dropped at grazing"
        f" incidence); position error {np.round(error, 1).tolist()} mm, sigma"
        f" {np.round(sigma, 1).tolist()} mm; mean residual"
        f" {perception.fit.mean_residual * 1e3:.2f} mm; u = {perception.u:.3f}"
        + (
            f" (median of {len(perception.u_fits)} fits, spread {perception.u_spread:.3f})"
            if len(perception.u_fits) > 1
            else ""
        )
    )
    try:
        from openup_ompl.perception.figure import plot_perception

        figure = plot_perception(perception, problem.object, args.out / "perception.png")
        print(f"figure written to {figure}")
    except MissingExtra as missing:
        print(f"no figure: {missing}", file=sys.stderr)
    print(f"point cloud written to {paths['cloud']}")
    print(f"scene with the estimate written to {paths['scene']}")
    return 0


def closed_loop_command(args: argparse.Namespace) -> int:
    """``openup-ompl closed-loop``: perceive, plan and judge every view; write the CSV, the
    trials and the figure.

    Args:
        args: The parsed command line (``scene``, ``policies``, ``camera``, ``noise``,
            ``distance``, ``trials``, ``seed``, ``planner``, ``time``, ``execute``,
            ``out``, ``quiet``).

    Returns:
        0, or 130 when interrupted (the views that ended are written).

    Raises:
        ConfigError: A bad scene or option.
    """
    from openup_ompl.perception.closed_loop import (
        ClosedLoopOptions,
        closed_loop,
        finished_trials,
        kinematic_judge,
    )
    from openup_ompl.robustness import check_scene, default_robustness_scene

    problem = check_scene(args.scene or default_robustness_scene())
    options = ClosedLoopOptions(
        camera=scene_camera(problem, args.camera or []),
        policies=tuple(args.policies),
        noises=tuple(args.noise),
        distances=tuple(args.distance),
        trials=args.trials,
        first_seed=args.seed,
        planner=args.planner,
        time_limit=args.time,
        perception=perception_options(args),
    )

    def progress(line: str) -> None:
        if not args.quiet:
            print(line, file=sys.stderr)

    judge = kinematic_judge
    if args.execute == "physics":
        from openup_ompl.physics.sweep import physics_judge

        judge = physics_judge
    records: list[dict[str, Any]] = []
    interrupted = False
    try:
        closed_loop(problem, options, judge=judge, progress=progress, records=records)
    except KeyboardInterrupt:
        # Keep what ended: a physics run takes minutes, and every view is seeded, so
        # the rest can be run with --seed.
        records = finished_trials(records, len(options.policies))
        interrupted = True
        if not records:
            print("openup-ompl: interrupted before any trial ended", file=sys.stderr)
            return 130
    title = (
        f"closed loop, {problem.robot.name}: perceive, plan at the estimate,"
        f" execute ({args.execute})"
    )
    write_closed_loop(records, args.out, title)
    if interrupted:
        views = len(records) // len(options.policies)
        print(
            f"openup-ompl: interrupted: the {views} views that ended are written",
            file=sys.stderr,
        )
    return 130 if interrupted else 0


def write_closed_loop(records: list[dict[str, Any]], out: Path, title: str = "") -> None:
    """Write a closed loop's tables and figure into ``out`` and print them: the per-cell
    table with Wilson 95 % intervals (``closed_loop.csv``), every trial
    (``closed_loop_trials.json``), every policy against the covariance rule (or the first
    policy) with the exact McNemar test (``closed_loop_pairs.csv``) and the figure
    (``closed_loop.png``, when matplotlib is installed).

    Args:
        records: The trials' records (:func:`~openup_ompl.perception.closed_loop.closed_loop`;
            several runs' records may be joined, e.g. seed ranges run in parallel).
        out: The output directory (created).
        title: The figure's title.
    """
    import json

    from openup_ompl.perception.closed_loop import summarize, write_csv
    from openup_ompl.perception.closed_loop_pairs import (
        POOLED,
        compare_policies,
        default_reference,
        write_pairs_csv,
    )

    rows = summarize(records)
    out.mkdir(parents=True, exist_ok=True)
    csv_path = write_csv(rows, out / "closed_loop.csv")
    trials = out / "closed_loop_trials.json"
    trials.write_text(json.dumps(records, indent=1, default=str) + "\n")
    for row in rows:
        mean_u = "none" if row["mean_u"] is None else f"{row['mean_u']:.3f}"
        unseen = f", {row['not_seen']} not seen" if row["not_seen"] else ""
        print(
            f"{row['policy']:>10}  noise {row['noise']:<4g} distance {row['distance']:<4g}"
            f" {row['successes']}/{row['trials']}"
            f" [{100 * row['ci_low']:.0f}, {100 * row['ci_high']:.0f}] %"
            f" (mean u {mean_u}{unseen})"
        )
    reference = default_reference([str(r["policy"]) for r in records])
    pairs = compare_policies(records, reference)
    pairs_path = write_pairs_csv(pairs, out / "closed_loop_pairs.csv")
    for pair in (p for p in pairs if p["noise"] == POOLED):
        print(
            f"{pair['policy']:>10} vs {reference}, all views: {pair['policy_successes']} vs"
            f" {pair['reference_successes']} of {pair['views']}, discordant"
            f" {pair['policy_only']} / {pair['reference_only']}, exact McNemar"
            f" p = {pair['p_value']:.3g}"
        )
    print(f"table written to {csv_path}; every trial in {trials}; pairs in {pairs_path}")
    try:
        from openup_ompl.perception.figure import plot_closed_loop

        print(f"plot written to {plot_closed_loop(rows, out / 'closed_loop.png', title)}")
    except MissingExtra as missing:
        print(f"no plot: {missing}", file=sys.stderr)
