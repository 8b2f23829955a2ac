"""The approach a plan's trials share (``PhysicsOptions.shared_approach``,
:mod:`openup_ompl.physics.approach`): the robot's motion bit for bit, no contact skipped,
the verdicts of the fixed sets."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("mujoco")
sys.path.insert(0, str(Path(__file__).resolve().parent))

import physics_regression as regression  # noqa: E402

from openup_ompl.exceptions import ConfigError  # noqa: E402
from openup_ompl.physics import PhysicsOptions, Rollout  # noqa: E402
from openup_ompl.physics.approach import STRIDE, SharedApproach  # noqa: E402
from openup_ompl.physics.world import NEIGHBOUR, OBJECT, ROBOT  # noqa: E402

SHARED = PhysicsOptions(early_end=True, shared_approach=True)
#: The one trial of the fixed sets whose verdict rounding decides: a start moved by
#: 1e-10 m or 1e-7 m along x turns its "dropped" into held
#: (``benchmarks/physics_sensitivity.py``).
ROUNDING_DECIDED = {("panda_can", 2, (0.02, 0.0, 0.0))}


@pytest.fixture(scope="module")
def panda() -> Rollout:
    """The regression set's Panda plan, its trials sharing the approach."""
    return Rollout(regression.plan_contents(regression.load()[0]), SHARED)


def _start(rollout: Rollout, offset: tuple[float, float, float]) -> np.ndarray:
    """Reset the rollout's simulation with the object at ``offset``; its start qpos."""
    rollout._start(offset[0], offset[1], 0, offset[2])
    world = rollout.world
    return rollout.sim.qpos[world.object_qpos : world.object_qpos + 7].copy()


@pytest.mark.parametrize(
    "offset", [(0.0, 0.0, 0.0), (0.0, 0.01, 0.0), (0.02, 0.0, 0.0), (0.01, 0.0, 0.3)]
)
def test_at_the_handover_the_robot_is_the_unshared_run_s(panda, offset):
    """Stepping the whole world without sharing up to a trial's handover: no robot geom
    touched the object before it, and the merged state there has the robot's positions,
    velocities and warm start to the last bit, the object's within a micrometre (its
    tilt, a rest's rocking, within 1e-5)."""
    import mujoco

    world, model = panda.world, panda.world.model
    shared = SharedApproach(panda)
    handover = shared.handover(_start(panda, offset))
    assert handover is not None and handover.end % STRIDE == 0
    sim = panda.sim
    _start(panda, offset)
    kinds = world.geom_kind
    for row in shared.rows[: handover.end]:
        sim.ctrl[world.actuator] = row
        mujoco.mj_step(model, sim)
        pairs = {tuple(sorted(kinds[g] for g in c.geom)) for c in sim.contact[: sim.ncon]}
        assert (ROBOT, OBJECT) not in pairs and (ROBOT, NEIGHBOUR) not in pairs
    state = np.empty(mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS))
    mujoco.mj_getState(model, sim, state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    merged = handover._states(handover.end, handover.end + 1)[0]
    qpos, qvel = 1 + world.qpos, 1 + model.nq + world.dof
    assert np.array_equal(merged[qpos], state[qpos])
    assert np.array_equal(merged[qvel], state[qvel])
    robot = np.ones(model.nv, dtype=bool)
    robot[world.object_dof : world.object_dof + 6] = False
    warm = shared.run.warm[handover.end]
    assert np.array_equal(warm[robot], sim.qacc_warmstart[robot])
    q = 1 + world.object_qpos
    assert np.abs(merged[q : q + 3] - state[q : q + 3]).max() < 1e-6  # [m]
    assert np.abs(merged[q + 3 : q + 7] - state[q + 3 : q + 7]).max() < 1e-5  # its rocking


def test_the_quick_trials_keep_their_verdicts_and_share_most_steps(panda):
    """The quick tier's three trials (held, pushed, dropped) and the turned can give their
    recorded verdicts with the approach shared, and take over late in the reach."""
    case = regression.load()[0]
    for trial in [*case["trials"][:3], case["trials"][6]]:
        assert trial["offset"][2] == 0.3 or trial in case["trials"][:3]
        record = panda.run(trial["offset"], frames=False)
        assert (record.success, record.cause) == (trial["success"], trial["cause"])
    handover = panda._shared.handover(_start(panda, (0.0, 0.0, 0.0)))  # type: ignore[union-attr]
    assert handover is not None and handover.end > 0.7 * panda.reach_targets.steps


def test_trials_do_not_depend_on_their_order():
    """The same offsets in two orders, each through a fresh rollout: the same records."""
    case = regression.load()[0]
    offsets = [t["offset"] for t in case["trials"][:4]]
    first = Rollout(regression.plan_contents(case), SHARED)
    second = Rollout(regression.plan_contents(case), SHARED)
    a = {tuple(o): first.run(o, frames=False).to_dict(frames=False) for o in offsets}
    b = {tuple(o): second.run(o, frames=False).to_dict(frames=False) for o in offsets[::-1]}
    assert a == b


def test_what_cannot_share_runs_whole(panda):
    """An object moved off its table or lifted, one turned about a horizontal axis, and a
    run that keeps frames do not share; the frames run is the unshared one to the last
    bit."""
    shared = SharedApproach(panda)
    assert shared.handover(_start(panda, (0.0, 0.9, 0.0))) is None
    start = _start(panda, (0.0, 0.0, 0.0))
    assert shared.handover(start + [0, 0, 1e-3, 0, 0, 0, 0]) is None
    tilted = start.copy()
    tilted[3:] = [np.cos(0.05), np.sin(0.05), 0.0, 0.0]
    assert shared.handover(tilted) is None
    assert shared.handover(start) is not None
    plain = Rollout(regression.plan_contents(regression.load()[0]), PhysicsOptions(early_end=True))
    a = panda.run((0.0, 0.01, 0.0), frames=True).to_dict()
    b = plain.run((0.0, 0.01, 0.0), frames=True).to_dict()
    a["options"].pop("shared_approach"), b["options"].pop("shared_approach")
    assert a == b


def test_the_option_is_checked():
    """``shared_approach`` is a bool; the sweep takes it with physics only."""
    from openup_ompl.robustness import RobustnessOptions

    with pytest.raises(ConfigError, match="shared_approach"):
        PhysicsOptions(shared_approach=1)  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="shared_approach"):
        RobustnessOptions(shared_approach=True)
    assert RobustnessOptions(execute="physics", shared_approach=True).shared_approach


def test_the_sweep_keeps_shared_shards_apart():
    """A physics sweep with the shared approach passes it to its tasks, under keys of
    their own (its records are not the unshared sweep's)."""
    from openup_ompl.robustness import RobustnessOptions, make_tasks

    scene = regression.ROOT / "scenes" / "panda_can.toml"
    plain = make_tasks(scene, RobustnessOptions(execute="physics", seeds=1, us=(0.5,)))
    shared = make_tasks(
        scene, RobustnessOptions(execute="physics", seeds=1, us=(0.5,), shared_approach=True)
    )
    assert shared[0].kwargs["shared_approach"] is True
    assert "shared_approach" not in plain[0].kwargs
    assert shared[0].key != plain[0].key


@pytest.mark.slow
def test_the_throughput_set_keeps_its_verdicts_but_the_rounding_decided_one():
    """The 126 throughput trials with the approach shared: every verdict the recorded one
    except, possibly, the trial whose verdict rounding decides; most trials share."""
    changed, shared = set(), 0
    for case in regression.load(regression.TRIALS):
        rollout = Rollout(regression.plan_contents(case), SHARED)
        for trial in case["trials"]:
            record = rollout.run(trial["offset"], frames=False)
            if (record.success, record.cause) != (trial["success"], trial["cause"]):
                changed.add((case["scene"], case["seed"], tuple(trial["offset"])))
            start = _start(rollout, tuple(trial["offset"]))  # type: ignore[arg-type]
            shared += rollout._shared.handover(start) is not None  # type: ignore[union-attr]
    assert changed <= ROUNDING_DECIDED
    assert shared >= 120


def test_an_object_near_a_fixed_obstacle_shares_while_clear_of_it():
    """Among the pillars (the back one's surface 55 mm behind the can's): moved 50 mm
    towards it the can still shares; moved 60 mm it would stand in it and does not."""
    import openup_ompl as oo

    problem = oo.load_scene(regression.ROOT / "benchmarks" / "unseen" / "panda" / "pillars.toml")
    plan = oo.GraspPlanningSetup(problem).solve(time_limit=5.0, planner="ikbirrt", seed=11)
    rollout = Rollout(plan, SHARED)
    shared = SharedApproach(rollout)
    assert shared.handover(_start(rollout, (0.05, 0.0, 0.0))) is not None
    assert shared.handover(_start(rollout, (0.06, 0.0, 0.0))) is None
