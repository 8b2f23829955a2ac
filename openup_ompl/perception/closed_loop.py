"""The closed loop: perceive, plan at the estimate with a policy's ``u``, judge against the
true pose.

Per trial (one seed): a fresh noisy view of the object where it truly is
(:func:`~openup_ompl.perception.perceive.perceive`) gives the estimated pose and the
covariance ``u``; for every policy (a fixed ``u``, or ``"covariance"``) the grasp is planned
for the object at the estimate (the grasp pose moves with the estimate: it is defined
relative to the object), and the plan is judged against the scene where the object truly
is. All policies of a trial share its view, so that they are compared on the same errors.

The judge is one argument, ``judge(setup, plan, truth) -> trial dict`` with at least
``success`` (bool): :func:`kinematic_judge` (the default) re-checks the plan against the
true scene and closes the hand there (:func:`openup_ompl.robustness.execute`); a physics
judge can replace it without touching the loop.
"""

from __future__ import annotations

import csv
import dataclasses
import math
from collections import Counter
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from openup_ompl._io import make_dir
from openup_ompl.exceptions import ConfigError, InvalidProblem, PerceptionError, PlanningFailed
from openup_ompl.executor import reseed_ompl
from openup_ompl.perception.camera import CameraOptions, DepthCamera, camera_of_scene
from openup_ompl.perception.extrinsic import PerceptionOptions
from openup_ompl.perception.noise import NoiseOptions
from openup_ompl.perception.perceive import at_estimate, perceive
from openup_ompl.planning import check_planner, check_time_limit
from openup_ompl.robustness import check_seeds, execute
from openup_ompl.scene import Problem, Shape
from openup_ompl.study.stats import wilson_interval

if TYPE_CHECKING:
    from openup_ompl.plan import Plan
    from openup_ompl.planning import GraspPlanningSetup

__all__ = [
    "CSV_COLUMNS",
    "MAX_TRIALS",
    "ClosedLoopOptions",
    "Judge",
    "closed_loop",
    "finished_trials",
    "kinematic_judge",
    "read_csv",
    "summarize",
    "write_csv",
]

#: The columns of the experiment's CSV (the closed loop results page), then diagnostics.
CSV_COLUMNS = (
    "policy",
    "noise",
    "distance",
    "trials",
    "successes",
    "success_rate",
    "ci_low",
    "ci_high",
    "mean_u",
    "mean_error_mm",
    "planning_failures",
    "not_seen",
)
#: Most views per noise and distance accepted (``trials``).
MAX_TRIALS = 10_000

Judge = Callable[["GraspPlanningSetup", "Plan", Problem], dict[str, Any]]


@dataclass(frozen=True)
class ClosedLoopOptions:
    """The experiment's sweep.

    Attributes:
        policies: ``u`` values in [0, 1] (as text, e.g. ``"0.3"``) and/or ``"covariance"``,
            distinct.
        noises: Sensor noise scales (:class:`NoiseOptions` ``scale``), distinct.
        distances: Camera distances [m] to the object (the default camera pose
            otherwise), distinct.
        trials: Views (seeds) per noise and distance.
        first_seed: Seed of trial 0 (trial ``i``: ``first_seed + i``), for noise and plan.
        planner: Planner name.
        time_limit: Planning time limit [s].
        camera: Other camera options (``distance`` is swept; with an explicit
            ``position`` there is one view, and ``distances`` must hold one value);
            ``None``: the scene file's ``[camera]`` table, as ``openup-ompl closed-loop``
            reads it (:func:`~openup_ompl.perception.camera.camera_of_scene`).
        perception: The camera's calibration errors and the estimator's restarts
            (:class:`~openup_ompl.perception.extrinsic.PerceptionOptions`).
    """

    policies: tuple[str, ...] = ("0", "0.3", "1", "covariance")
    noises: tuple[float, ...] = (1.0, 2.0, 4.0)  # as `openup-ompl closed-loop`
    distances: tuple[float, ...] = (0.6, 1.0)  # [m]
    trials: int = 10
    first_seed: int = 1
    planner: str = "ikbirrt"
    time_limit: float = 5.0  # [s]
    camera: CameraOptions | None = None
    perception: PerceptionOptions = field(default_factory=PerceptionOptions)

    def __post_init__(self) -> None:
        for name in ("policies", "noises", "distances"):
            value = getattr(self, name)
            if isinstance(value, (str, bytes)) or not value:
                raise ConfigError(name, value, "a non-empty list")
        keys: list[object] = []
        for policy in self.policies:
            if policy != "covariance":
                try:
                    value = float(policy)
                except (TypeError, ValueError):
                    value = math.nan
                if not 0 <= value <= 1:
                    raise ConfigError("policy", policy, "a u in [0, 1] or 'covariance'")
                keys.append(value)
            else:
                keys.append(policy)
        # A value given twice would count the same views twice in its row.
        for name, values in (
            ("policies", keys),
            ("noises", list(self.noises)),
            ("distances", list(self.distances)),
        ):
            if len(set(values)) != len(values):
                raise ConfigError(name, list(getattr(self, name)), "distinct values")
        # Each distance checked as a camera's (the scene's camera is known only later).
        self.cameras(self.camera if self.camera is not None else CameraOptions())
        check_seeds(self.first_seed, self.trials, MAX_TRIALS, "trials")
        for name in ("first_seed", "trials"):  # numpy integers accepted, stored as int
            object.__setattr__(self, name, int(getattr(self, name)))
        for noise in self.noises:
            NoiseOptions(scale=noise)
        check_planner(self.planner)
        check_time_limit(self.time_limit, "time")

    def cameras(self, camera: CameraOptions) -> list[CameraOptions]:
        """``camera`` at each of the swept distances.

        Args:
            camera: The camera options (an orbit, or an explicit position).

        Returns:
            One camera per distance of :attr:`distances` (the camera itself for an explicit
            position).

        Raises:
            ConfigError: More than one distance for a camera at an explicit position, or
                a bad distance.
        """
        if camera.position is not None and len(self.distances) > 1:
            raise ConfigError(
                "distances",
                list(self.distances),
                "one distance with an explicit camera position (it is not used: every "
                "distance would be the same view)",
            )
        return [dataclasses.replace(camera, distance=distance) for distance in self.distances]


def planar_offset(estimate: Shape, true: Shape) -> tuple[float, float, float]:
    """The true object's planar offset and yaw from the estimate.

    Args:
        estimate: The object at its estimated pose.
        true: The object at its true pose.

    Returns:
        ``(dx, dy, yaw)``: the position offset [m] along the world x and y axes and the
        turn [rad] about the estimate's own z axis.
    """
    dx, dy = (true.pose[:2] - estimate.pose[:2]).tolist()
    relative = estimate.placement.rotation.T @ true.placement.rotation
    return dx, dy, float(math.atan2(relative[1, 0], relative[0, 0]))


def kinematic_judge(setup: GraspPlanningSetup, plan: Plan, truth: Problem) -> dict[str, Any]:
    """:func:`openup_ompl.robustness.execute` against the true object: its planar offset
    and yaw from the estimate (the estimate's height and tilt errors are kept: the judge
    is planar, as the paper's experiment is).

    Args:
        setup: The setup the plan was made with (at the estimate).
        plan: The plan.
        truth: The true scene.

    Returns:
        The trial's verdict (:func:`openup_ompl.robustness.execute`'s record: success,
        collision, force closure, ...).
    """
    estimate, true = setup.problem.object, truth.object
    assert estimate is not None and true is not None
    dx, dy, yaw = planar_offset(estimate, true)
    torsion = setup.problem.robot.spec.torsion
    return execute(setup, plan, dx, dy, yaw, torsion=torsion)[0]


def _unseen_records(
    base: dict[str, Any], policies: Sequence[str], error: PerceptionError
) -> list[dict[str, Any]]:
    """A view with no estimate has nothing to plan: each policy's record says "not seen"
    (not a planning failure); a fixed policy still has its u, the covariance none."""
    return [
        {
            **base,
            "policy": policy,
            "u": None if policy == "covariance" else float(policy),
            "error_mm": None,
            "seen": False,
            "planned": False,
            "success": False,
            "error": str(error),
        }
        for policy in policies
    ]


def closed_loop(
    problem: Problem,
    options: ClosedLoopOptions | None = None,
    judge: Judge = kinematic_judge,
    progress: Callable[[str], None] | None = None,
    records: list[dict[str, Any]] | None = None,
) -> list[dict[str, Any]]:
    """Run every trial; returns one record per (noise, distance, seed, policy).

    ``records``: the list the records are appended to as the trials end (default: a new
    one); a caller that keeps it keeps the finished trials when the run is interrupted
    (:func:`finished_trials`).

    Args:
        problem: The true scene (its object where it really is).
        options: Policies, noise scales, distances, trials, seed, planner (default
            :class:`ClosedLoopOptions`).
        judge: How a plan is judged against the truth (:func:`kinematic_judge`, or the
            physics judge of :mod:`openup_ompl.physics.sweep`).
        progress: Called with a line per finished view (``None``: silent).
        records: The list the records are appended to as the trials end.

    Returns:
        The records: policy, noise, distance [m], seed, ``u``, the estimate's error
        [mm], whether it was seen, planned and succeeded, and the judge's fields.
    """
    from openup_ompl.planning import GraspPlanningSetup

    options = options or ClosedLoopOptions()
    if problem.object is None:
        raise ConfigError("scene: object", None, "an [object] to perceive and grasp")
    cameras = options.cameras(
        options.camera if options.camera is not None else camera_of_scene(problem)
    )
    records = [] if records is None else records
    for noise in options.noises:
        for distance, options_at in zip(options.distances, cameras, strict=True):
            camera = DepthCamera(problem, options_at)
            for i in range(options.trials):
                seed = options.first_seed + i
                base = {"noise": noise, "distance": distance, "seed": seed}
                try:
                    seen = perceive(
                        problem,
                        noise=NoiseOptions(scale=noise),
                        depth_camera=camera,
                        rng=np.random.default_rng(seed),
                        options=options.perception,
                    )
                except PerceptionError as error:
                    records.extend(_unseen_records(base, options.policies, error))
                    if progress is not None:
                        progress(
                            f"noise {noise:g}, distance {distance:g} m, seed {seed} done"
                            f" (not seen: {type(error).__name__})"
                        )
                    continue
                estimated = at_estimate(problem, seen.pose)
                error_mm = float(np.linalg.norm(seen.pose[:2] - problem.object.pose[:2]) * 1e3)
                for policy in options.policies:
                    u = seen.u if policy == "covariance" else float(policy)
                    record: dict[str, Any] = {
                        **base,
                        "policy": policy,
                        "u": u,
                        "error_mm": error_mm,
                        "seen": True,
                    }
                    # Every plan from its view's seed alone: OMPL's own draws (the path
                    # simplifier's) would otherwise depend on the plans made before it,
                    # so two policies with one u, or a run of a seed range, would differ.
                    reseed_ompl(seed)
                    try:
                        setup = GraspPlanningSetup(estimated, u=u)
                        plan = setup.solve(
                            time_limit=options.time_limit,
                            planner=options.planner,
                            seed=seed,
                            simplify=True,
                        )
                    except (PlanningFailed, InvalidProblem) as error:
                        records.append(
                            {**record, "success": False, "planned": False, "error": str(error)}
                        )
                        continue
                    trial = judge(setup, plan, problem)
                    # The loop's own fields (the trial's seed, policy, u) win over the
                    # judge's (a rollout's own jitter seed, say).
                    records.append({**trial, **record, "planned": True})
                if progress is not None:
                    progress(f"noise {noise:g}, distance {distance:g} m, seed {seed} done")
    return records


def finished_trials(records: list[dict[str, Any]], policies: int) -> list[dict[str, Any]]:
    """The records of the trials (views) that ended for all ``policies`` (an interrupted
    run's last view may have ended for some only).

    Args:
        records: The records so far.
        policies: The number of policies per view.

    Returns:
        The complete views' records, in order.
    """
    counts = Counter((r["noise"], r["distance"], r["seed"]) for r in records)
    return [r for r in records if counts[(r["noise"], r["distance"], r["seed"])] == policies]


def _mean(values: Iterable[float | None]) -> float | None:
    """The mean of the known (finite) values, ``None`` without any."""
    known = [float(v) for v in values if v is not None and math.isfinite(v)]
    return float(np.mean(known)) if known else None


def summarize(records: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per (policy, noise, distance) with the :data:`CSV_COLUMNS`: the success
    rate's Wilson 95 % interval (``ci_low``, ``ci_high``), ``mean_u`` and ``mean_error_mm``
    over the trials that have one (``None`` if none has), planning failures among the
    views that saw the object, and the views that did not (``not_seen``).

    Args:
        records: The trials' records (:func:`closed_loop`).

    Returns:
        The rows; rates in [0, 1], ``mean_error_mm`` [mm].
    """
    cells: dict[tuple[str, float, float], list[dict[str, Any]]] = {}
    for record in records:
        key = (record["policy"], record["noise"], record["distance"])
        cells.setdefault(key, []).append(record)
    rows = []
    for (policy, noise, distance), group in cells.items():
        successes = sum(bool(r["success"]) for r in group)
        low, high = wilson_interval(successes, len(group))
        rows.append(
            {
                "policy": policy,
                "noise": noise,
                "distance": distance,
                "trials": len(group),
                "successes": successes,
                "success_rate": successes / len(group),
                "ci_low": low,
                "ci_high": high,
                "mean_u": _mean(r["u"] for r in group),
                "mean_error_mm": _mean(r["error_mm"] for r in group),
                "planning_failures": sum(r.get("seen", True) and not r["planned"] for r in group),
                "not_seen": sum(not r.get("seen", True) for r in group),
            }
        )
    return rows


def _decimals(value: float | None, digits: int) -> str:
    return "" if value is None else f"{value:.{digits}f}"


def write_csv(rows: Sequence[dict[str, Any]], path: Path) -> Path:
    """The experiment's CSV: :data:`CSV_COLUMNS`, one row per cell (an unknown mean left
    empty).

    Args:
        rows: The rows of :func:`summarize`.
        path: The CSV file to write.

    Returns:
        ``path``.
    """
    make_dir(path.parent)
    with path.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(CSV_COLUMNS))
        writer.writeheader()
        for row in rows:
            writer.writerow(
                {
                    **row,
                    "success_rate": _decimals(row["success_rate"], 4),
                    "ci_low": _decimals(row["ci_low"], 4),
                    "ci_high": _decimals(row["ci_high"], 4),
                    "mean_u": _decimals(row["mean_u"], 4),
                    "mean_error_mm": _decimals(row["mean_error_mm"], 3),
                }
            )
    return path


def read_csv(path: Path) -> list[dict[str, Any]]:
    """Rows of a CSV written by :func:`write_csv`, numbers as numbers (an empty mean as
    ``None``).

    Args:
        path: The CSV file.

    Returns:
        One dictionary per row, keyed by :data:`CSV_COLUMNS`.
    """
    with path.open(newline="") as handle:
        rows = list(csv.DictReader(handle))
    ints = ("trials", "successes", "planning_failures", "not_seen")
    floats = ("noise", "distance", "success_rate", "ci_low", "ci_high", "mean_u", "mean_error_mm")

    def number(key: str, value: str) -> Any:
        if key in ints:
            return int(value)
        if key in floats:
            return float(value) if value else None
        return value

    return [{key: number(key, value) for key, value in row.items()} for row in rows]
