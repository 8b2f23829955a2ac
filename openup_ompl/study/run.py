"""The study's trials: draw, believe, plan with every policy, execute in physics.

One trial of a ``(family, error)`` cell has one deterministic seed sequence
(:func:`trial_seeds`: NumPy's ``SeedSequence`` of the study's seed and the family's,
error's and trial's names), split into three streams: the instance (the family's draw),
the error (the direct error or the camera's noise) and the plan seed. Every policy of the
trial sees the same instance, the same belief and the same plan seed (pairing). Before
each plan OMPL's process-wide generator is reseeded from the plan seed, so that a plan
depends on its problem, ``u`` and seed alone, not on what the process planned before; two
policies that give the same ``u`` share one plan and one rollout (they are the same run).

Each plan is executed in physics against the true scene
(:func:`~openup_ompl.physics.sweep.physics_judge`: the project's rollout, reach, close,
lift and hold). A trial's verdict per policy: ``held`` (the rollout's success), a plan
failure (nothing to execute: not held), ``obstacle_contact`` (a robot link touched an
obstacle, which also fails the rollout) and ``disturbed`` (a neighbour moved or tipped:
``None`` until the rollout reports it).

The executor's unit (:class:`~openup_ompl.executor.Task`) is a chunk of trials of one
cell (:func:`study_chunk`), so a killed run resumes from the chunks it finished.
"""

from __future__ import annotations

import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from openup_ompl.exceptions import ConfigError, InvalidProblem, PlanningFailed
from openup_ompl.executor import (
    SEED_LIMIT,
    Task,
    check_generator_seed,
    reseed_ompl,
    settings_digest,
)
from openup_ompl.planning import check_planner, check_time_limit
from openup_ompl.scene import Problem
from openup_ompl.study.errors import ErrorSource, believe, parse_error
from openup_ompl.study.families import Family, instance_problem, template_scene
from openup_ompl.study.geometry import HandSweep
from openup_ompl.study.policies import FALLBACK_U, check_policies, policy_u

if TYPE_CHECKING:
    from openup_ompl.plan import Plan
    from openup_ompl.planning import GraspPlanningSetup

__all__ = [
    "MAX_TRIALS",
    "StudyOptions",
    "make_tasks",
    "plan_at_belief",
    "run_trial",
    "study_chunk",
    "trial_seeds",
]

#: Most trials per cell accepted.
MAX_TRIALS = 100_000
#: Trials per task (one shard file) by default.
CHUNK = 10


@dataclass(frozen=True)
class StudyOptions:
    """The study's sweep.

    Attributes:
        families: Scene families (:func:`~openup_ompl.study.families.parse_families`).
        errors: Error source names (:func:`~openup_ompl.study.errors.parse_error`).
        policies: Policy names (:func:`~openup_ompl.study.policies.check_policies`).
        trials: Paired trials per ``(family, error)`` cell.
        seed: The study's seed (every trial's seeds derive from it).
        planner: Planner name.
        time_limit: Planning time limit [s] per plan.
        chunk: Trials per executor task (and shard file).
    """

    families: tuple[Family, ...]
    errors: tuple[str, ...] = ("pose-0.5cm", "pose-1cm", "pose-2cm", "perceived")
    policies: tuple[str, ...] = ("0", "0.3", "0.6", "1", "covariance", "adaptive")
    trials: int = 20
    seed: int = 1
    planner: str = "ikbirrt"
    time_limit: float = 5.0  # [s]
    chunk: int = CHUNK

    def __post_init__(self) -> None:
        if not self.families:
            raise ConfigError("families", list(self.families), "at least one family")
        if isinstance(self.errors, str) or not self.errors:
            raise ConfigError("errors", self.errors, "a non-empty list of error sources")
        for name in self.errors:
            parse_error(name)
        if len(set(self.errors)) != len(self.errors):
            raise ConfigError("errors", list(self.errors), "distinct error sources")
        names = [f.name for f in self.families]
        if len(set(names)) != len(names):
            raise ConfigError("families", names, "distinct families")
        object.__setattr__(self, "policies", check_policies(self.policies))
        for name, value in (("trials", self.trials), ("chunk", self.chunk)):
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                raise ConfigError(name, value, f"an integer in [1, {MAX_TRIALS}]")
            if not 1 <= value <= MAX_TRIALS:
                raise ConfigError(name, value, f"an integer in [1, {MAX_TRIALS}]")
        check_generator_seed(self.seed)
        check_planner(self.planner)
        check_time_limit(self.time_limit, "time")


def _name_key(name: str) -> int:
    """A stable 32-bit integer of a name (CRC-32)."""
    return zlib.crc32(name.encode())


def trial_seeds(
    seed: int, family: str, error: str, trial: int
) -> tuple[np.random.Generator, np.random.Generator, int]:
    """A trial's generators and plan seed, independent streams of one seed sequence.

    Args:
        seed: The study's seed.
        family: The family's name.
        error: The error source's name.
        trial: The trial's index.

    Returns:
        ``(instance_rng, error_rng, plan_seed)``; ``plan_seed`` in ``[1, SEED_LIMIT)``.
    """
    sequence = np.random.SeedSequence([seed, _name_key(family), _name_key(error), trial])
    instance, error_stream, plan = sequence.spawn(3)
    plan_seed = int(plan.generate_state(1)[0]) % (SEED_LIMIT - 1) + 1
    return np.random.default_rng(instance), np.random.default_rng(error_stream), plan_seed


def plan_at_belief(
    believed: Problem, u: float, plan_seed: int, planner: str, time_limit: float
) -> tuple[GraspPlanningSetup, Plan]:
    """A trial's plan for one ``u``, as the study makes it: OMPL's generator restarted from
    ``plan_seed`` (the plan depends on its seed alone), the simplified path.

    Args:
        believed: The scene at the believed pose.
        u: The hand law's uncertainty parameter, in [0, 1].
        plan_seed: The trial's plan seed (:func:`trial_seeds`).
        planner: A planner name.
        time_limit: Planning time [s].

    Returns:
        The setup and its plan.

    Raises:
        PlanningFailed, InvalidProblem: No plan (the study counts it as ``plan failed``).
    """
    from openup_ompl.planning import GraspPlanningSetup, PlanningOptions

    reseed_ompl(plan_seed)
    options = PlanningOptions(u=u, planner=planner, time_limit=time_limit, simplify=True)
    setup = GraspPlanningSetup(believed, options)
    return setup, setup.solve(seed=plan_seed)


def _execute(
    believed: Problem, truth: Problem, u: float, plan_seed: int, planner: str, time_limit: float
) -> dict[str, Any]:
    """Plan at the belief with ``u``, execute against the truth in physics."""
    from openup_ompl.physics.sweep import physics_judge

    try:
        setup, plan = plan_at_belief(believed, u, plan_seed, planner, time_limit)
    except (PlanningFailed, InvalidProblem) as error:
        return {"planned": False, "held": False, "cause": "plan failed", "error": str(error)}
    trial = physics_judge(setup, plan, truth)
    # A rollout that simulates movable neighbours reports their disturbance; one that
    # does not (static obstacles) leaves it unknown.
    reported = "neighbour_moved" in trial
    disturbed = bool(trial["neighbour_moved"] or trial["neighbour_tipped"]) if reported else None
    return {
        "planned": True,
        "held": bool(trial["success"]),
        "cause": trial.get("cause"),
        "obstacle_contact": bool(trial.get("collision")),
        "disturbed": disturbed,
        "neighbour_touched": trial.get("neighbour_touched"),
        "touched": bool(trial.get("touched")),
        "verdict": trial.get("verdict"),
    }


def run_trial(
    family: Family,
    template: Problem,
    source: ErrorSource,
    policies: Sequence[str],
    trial: int,
    *,
    seed: int,
    planner: str = "ikbirrt",
    time_limit: float = 5.0,
    mesh_dir: Path | None = None,
) -> dict[str, Any]:
    """One paired trial: every policy on the same instance, belief and plan seed.

    Args:
        family: The family the instance is drawn from.
        template: Its template scene (:func:`~openup_ompl.study.families.template_scene`).
        source: The error source.
        policies: The policies, canonical names.
        trial: The trial's index.
        seed: The study's seed.
        planner: A planner name (:data:`~openup_ompl.planning_options.PLANNERS`).
        time_limit: Planning time per plan [s].
        mesh_dir: Directory of the mesh family's OBJ files.

    Returns:
        ``{"trial", "plan_seed", "object", "obstacles", "offset", "refusal", "safe_u",
        "results": {policy: {"u", "planned", "held", "cause", "obstacle_contact",
        "disturbed", ...}}}``; ``safe_u`` is the ``capped`` policy's cap (``None``
        without it), and an ``adaptive`` result that fell back carries ``fallback_from``,
        the ``u`` whose plan failed.
    """
    instance_rng, error_rng, plan_seed = trial_seeds(seed, family.name, source.name, trial)
    truth = instance_problem(family, instance_rng, template, mesh_dir)
    belief = believe(truth, source, error_rng)
    assert truth.object is not None
    record: dict[str, Any] = {
        "trial": trial,
        "plan_seed": plan_seed,
        "object": {k: v for k, v in truth.object.to_table().items() if k != "file"},
        "obstacles": len(truth.obstacles),
        "offset": list(belief.offset),
        "refusal": belief.refusal,
        "safe_u": None,
        "results": {},
    }
    if belief.believed is None or belief.evidence is None:
        for policy in policies:
            record["results"][policy] = {
                "u": None, "planned": False, "held": False, "cause": "not seen",
            }  # fmt: skip
        return record
    safe = None
    if "capped" in policies:
        safe = HandSweep(belief.believed).largest_safe_u()
        record["safe_u"] = safe
    believed = belief.believed
    done: dict[float, dict[str, Any]] = {}

    def outcome(u: float) -> dict[str, Any]:
        if u not in done:
            done[u] = _execute(believed, truth, u, plan_seed, planner, time_limit)
        return {"u": u, **done[u]}

    for policy in policies:
        result = outcome(round(policy_u(policy, belief.evidence, believed, safe), 9))
        if policy == "adaptive" and not result["planned"] and result["u"] != FALLBACK_U:
            # No collision-free path at the needed opening: the scene allows less.
            result = {**outcome(FALLBACK_U), "fallback_from": result["u"]}
        record["results"][policy] = result
    return record


def study_chunk(
    seed: int,
    family: dict[str, Any],
    error: str,
    start: int,
    stop: int,
    policies: Sequence[str],
    study_seed: int,
    planner: str,
    time_limit: float,
    mesh_dir: str,
) -> dict[str, Any]:
    """Trials ``start`` to ``stop - 1`` of one cell (an executor task; ``seed`` is the
    executor's and unused: each trial's seeds derive from ``study_seed``).

    Args:
        seed: The executor's task seed (unused).
        family: The family, as :meth:`~openup_ompl.study.families.Family.to_json`.
        error: The error source's name.
        start, stop: The trials' index range.
        policies, planner, time_limit: As for :func:`run_trial`.
        study_seed: The study's seed.
        mesh_dir: Directory of the mesh family's OBJ files.

    Returns:
        ``{"family", "error", "start", "stop", "trials"}``, the trials' records.
    """
    fam = Family.from_json(family)
    template = template_scene(fam)
    source = parse_error(error)
    trials = [
        run_trial(
            fam,
            template,
            source,
            policies,
            i,
            seed=study_seed,
            planner=planner,
            time_limit=time_limit,
            mesh_dir=Path(mesh_dir),
        )  # fmt: skip
        for i in range(start, stop)
    ]
    return {"family": fam.name, "error": error, "start": start, "stop": stop, "trials": trials}


def make_tasks(options: StudyOptions, mesh_dir: Path) -> list[Task]:
    """One task per ``(family, error, chunk of trials)``; each key carries a digest of
    every setting and of the files the family is drawn from, so that a rerun into the same
    shards reuses a chunk only when nothing it depends on changed.

    Args:
        options: The study's settings.
        mesh_dir: Directory of the mesh family's OBJ files.

    Returns:
        The tasks, for :func:`~openup_ompl.executor.run_tasks`.
    """
    tasks = []
    for family in options.families:
        files = template_scene(family).source_files()
        for error in options.errors:
            shared = {
                "family": family.to_json(),
                "error": error,
                "policies": list(options.policies),
                "study_seed": options.seed,
                "planner": options.planner,
                "time_limit": float(options.time_limit),
            }
            digest = settings_digest(shared, files)
            for start in range(0, options.trials, options.chunk):
                stop = min(start + options.chunk, options.trials)
                key = f"{family.name}-{error}-t{start}-{stop}-{digest}"
                kwargs = {**shared, "start": start, "stop": stop, "mesh_dir": str(mesh_dir)}
                tasks.append(
                    Task(key=key, function="openup_ompl.study.run:study_chunk", kwargs=kwargs)
                )
    return tasks
