"""Damped least-squares IK of the palm frame."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from openup_ompl.exceptions import ConfigError
from openup_ompl.ik import IKOptions, IKSolver


@pytest.fixture()
def target(panda):
    """A reachable palm pose: the palm at a random configuration inside the limits."""
    arm = np.random.default_rng(3).uniform(panda.arm_lower, panda.arm_upper)
    return panda.palm_placement(panda.model.createData(), panda.full_q(arm, np.zeros(2)))


def test_solutions_reach_the_target_within_tolerance(panda, target):
    """Every solution returned puts the palm on the target within the tolerances."""
    solver = IKSolver(panda, target)
    rng = np.random.default_rng(0)
    found = [solver.solve(rng) for _ in range(5)]
    assert any(arm is not None for arm in found)
    for arm in (a for a in found if a is not None):
        position, rotation = solver.error(arm)
        assert position < solver.options.position_tolerance
        assert rotation < solver.options.rotation_tolerance
        assert np.all(arm >= panda.arm_lower) and np.all(arm <= panda.arm_upper)


def test_unreachable_target_stalls_early(panda):
    """A target out of reach is abandoned at a stall check, well before the budget."""
    far = pin.SE3(np.eye(3), np.array([3.0, 0.0, 0.5]))
    solver = IKSolver(panda, far, IKOptions(max_iterations=150, stall_iterations=10))
    assert solver.refine(panda.spec.home) is None
    assert solver.iterations < 100
    patient = IKSolver(panda, far, IKOptions(max_iterations=150, stall_ratio=1e9))
    assert patient.refine(panda.spec.home) is None
    assert patient.iterations == 150


@pytest.mark.parametrize(
    "field, value",
    [
        ("max_iterations", 0),
        ("stall_iterations", 0),
        ("stall_ratio", 0.0),
        ("damping", -1.0),
        # Looser than a plan file accepts at its last row (PlanFile's grasp check).
        ("position_tolerance", 0.02),
        ("rotation_tolerance", 0.2),
    ],
)
def test_bad_options_are_named(field, value):
    """A bad IK option raises ConfigError naming the option."""
    with pytest.raises(ConfigError, match=field):
        IKOptions(**{field: value})


def test_palm_step_translates_the_palm_and_holds_its_orientation(panda):
    """A palm step moves the palm by the requested offset in its own frame, its
    orientation held, within the IK tolerances, from most configurations."""
    solver = IKSolver(panda, pin.SE3.Identity())
    options = solver.options
    data = panda.model.createData()
    rng = np.random.default_rng(5)
    reached = 0
    for _ in range(50):
        arm = rng.uniform(0.6 * panda.arm_lower, 0.6 * panda.arm_upper)
        offset = rng.normal(size=3)
        offset *= 0.025 / np.linalg.norm(offset)
        stepped = solver.palm_step(arm, offset)
        if stepped is None:
            continue
        reached += 1
        before = panda.palm_placement(data, panda.full_q(arm, np.zeros(2)))
        after = panda.palm_placement(data, panda.full_q(stepped, np.zeros(2)))
        moved = before.actInv(after)
        assert np.linalg.norm(moved.translation - offset) < options.position_tolerance
        assert np.linalg.norm(pin.log3(moved.rotation)) < options.rotation_tolerance
    assert reached >= 35
