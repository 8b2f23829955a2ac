"""The paper's experiment judged in physics: one executor task per ``(u, seed)``.

The task plans exactly as the kinematic one does
(:func:`~openup_ompl.robustness.robustness_run`: same scene, planner, seed, law), then
runs every perturbation of the object through one
:class:`~openup_ompl.physics.rollout.Rollout` of that plan. Each trial is the rollout's
execution record (without the viewer's frames) plus the sweep's keys (``dx, dy, yaw,
success, collision``; ``collision``: a robot link touched an obstacle in physics). Trials
end early once their verdict is certain (``PhysicsOptions.early_end``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from openup_ompl.physics.options import PhysicsOptions

if TYPE_CHECKING:
    from openup_ompl.plan import Plan
    from openup_ompl.planning import GraspPlanningSetup
    from openup_ompl.scene import Problem

__all__ = ["physics_judge", "physics_run", "physics_trial"]


def physics_trial(record: dict[str, Any]) -> dict[str, Any]:
    """A sweep trial of an execution record's contents (``to_dict(frames=False)``).

    Args:
        record: An execution record as a dictionary, without frames.

    Returns:
        The trial's row: the offset (``dx``, ``dy`` [m], ``yaw`` [rad]), ``success``,
        ``collision`` (an obstacle touched) and the record's other fields.
    """
    offset = record["offset"]
    return {
        "dx": offset["dx"],
        "dy": offset["dy"],
        "yaw": offset["yaw"],
        "success": record["success"],
        "collision": bool(record["obstacle_contacts"]),
        **{k: v for k, v in record.items() if k not in ("offset", "options", "format")},
    }


def _diverged(error: Exception) -> dict[str, Any]:
    """A trial without a verdict (the simulation diverged): failed, saying why."""
    return {"success": False, "collision": False, "touched": False,
            "moved_before_closing": None, "cause": "diverged", "verdict": str(error)}  # fmt: skip


def physics_run(
    seed: int,
    scene: str,
    u: float,
    planner: str,
    time_limit: float,
    perturbations: Sequence[Sequence[float]],
    open_arrival: bool = False,
    shared_approach: bool = False,
    **_kinematic: Any,
) -> dict[str, Any]:
    """Plan once at the nominal pose, then execute every perturbation in physics (inside
    a task process). The kinematic grasp test's settings (``friction``, ``torsion``) are
    accepted and unused: physics has its own friction (the scene's).

    Args:
        seed: The planning seed.
        scene: The scene file's path.
        u: The uncertainty planned with, in [0, 1].
        planner: The planner's name.
        time_limit: The planning time limit [s].
        perturbations: ``(dx [m], dy [m], yaw [rad])`` object offsets to execute against.
        open_arrival: Plan with the open-arrival law.
        shared_approach: The plan's trials share its approach
            (``PhysicsOptions.shared_approach``).
        **_kinematic: The kinematic test's settings, unused.

    Returns:
        ``{"u", "seed", "planned", "error", "solve_time", "rows", "physics", "trials"}``.
    """
    from openup_ompl.exceptions import SimulationDiverged
    from openup_ompl.physics.rollout import Rollout
    from openup_ompl.robustness import plan_nominal

    options = PhysicsOptions(early_end=True, shared_approach=shared_approach)
    record, _, plan = plan_nominal(
        seed, scene, u, planner, time_limit, perturbations, open_arrival,
        failed={"touched": False, "moved_before_closing": None},
    )  # fmt: skip
    record["physics"] = dict(options.__dict__)
    if plan is None:
        return record
    rollout = Rollout(plan, options)
    record["trials"] = []
    for dx, dy, yaw in perturbations:
        try:
            trial = physics_trial(
                rollout.run((dx, dy, yaw), seed=seed, frames=False).to_dict(False)
            )
        except SimulationDiverged as error:  # no verdict: a failed trial that says why
            trial = {"dx": dx, "dy": dy, "yaw": yaw, **_diverged(error)}
        record["trials"].append(trial)
    return record


def physics_judge(setup: GraspPlanningSetup, plan: Plan, truth: Problem) -> dict[str, Any]:
    """The closed loop's judge in physics (:func:`~openup_ompl.perception.closed_loop.
    closed_loop`): the plan, made for the object where perception put it, executed in a
    world whose object stands where it truly is (its full pose: the estimate's height and
    tilt errors are not carried into the world, the object rests as it really does).

    Args:
        setup: The setup the plan was made with (at the estimate).
        plan: The plan.
        truth: The true scene.

    Returns:
        The rollout's sweep trial (:func:`physics_trial`); a diverged simulation is a
        failed trial with ``cause`` ``"diverged"``.
    """
    from openup_ompl.exceptions import SimulationDiverged
    from openup_ompl.perception.closed_loop import planar_offset
    from openup_ompl.physics.rollout import Rollout
    from openup_ompl.scene import Shape

    estimate, true = setup.problem.object, truth.object
    assert estimate is not None and true is not None
    # The world holds the truth, so the rollout's own offset is 0; the trial reports the
    # truth's planar offset from the estimate, as the kinematic judge does. The truth is
    # taken as a plan file holds an object (its table read back, the quaternion normalised
    # once more), which keeps the verdicts of the closed-loop runs bit for bit.
    dx, dy, yaw = planar_offset(estimate, true)
    true = Shape.from_table(true.to_table(), "truth object", is_object=True)
    try:
        rollout = Rollout(plan, PhysicsOptions(early_end=True), scene_object=true)
        record = rollout.run((0.0, 0.0, 0.0), frames=False).to_dict(False)
    except SimulationDiverged as error:
        trial = _diverged(error)
    else:
        trial = physics_trial(record)
    return {**trial, "dx": dx, "dy": dy, "yaw": yaw}
