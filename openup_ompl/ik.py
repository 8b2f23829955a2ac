"""Inverse kinematics of the palm frame: damped least squares on Pinocchio.

The error is ``log6(oMpalm^-1 * oMgoal)`` (palm frame), the step the damped
least-squares solution through the frame Jacobian composed with ``Jlog6``, as in
Pinocchio's own IK example, restricted to the arm joints and clipped to their limits.
Random restarts (uniform inside the joint limits) escape local minima; a restart that
stops making progress (joint limits, singularities) is abandoned early, since a fresh one
is cheaper than waiting out the iteration budget (``benchmarks/bench_ik.py``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from openup_ompl._model import selector
from openup_ompl._toml import is_finite, is_integer
from openup_ompl.exceptions import ConfigError
from openup_ompl.robot import Robot

#: The largest convergence thresholds IK accepts [m, rad]: a plan ends where IK put the
#: palm, and a plan file whose last row is further from its grasp pose is refused
#: (:class:`~openup_ompl.plan.PlanFile`).
MAX_POSITION_TOLERANCE = 0.01
MAX_ROTATION_TOLERANCE = 0.1


@dataclass(frozen=True)
class IKOptions:
    """Damped least-squares IK settings.

    Attributes:
        max_iterations: Iterations per restart.
        position_tolerance: Convergence threshold on the palm position error [m], at most
            :data:`MAX_POSITION_TOLERANCE`.
        rotation_tolerance: Convergence threshold on the palm rotation error [rad], at
            most :data:`MAX_ROTATION_TOLERANCE`.
        damping: Damping ``lambda`` of ``J J^T + lambda I`` [unitless].
        step: Fraction of the least-squares step taken per iteration.
        max_restarts: Random restarts tried by :meth:`IKSolver.solve` before giving up.
        stall_iterations: Progress is checked every this many iterations.
        stall_ratio: A restart is abandoned when its error (norm of ``log6``) is not below
            this fraction of its value ``stall_iterations`` earlier [unitless].
    """

    max_iterations: int = 150
    position_tolerance: float = 1e-5  # [m]
    rotation_tolerance: float = 1e-4  # [rad]
    damping: float = 1e-3
    step: float = 1.0
    max_restarts: int = 20
    stall_iterations: int = 10
    stall_ratio: float = 0.9

    def __post_init__(self) -> None:
        for name in ("max_iterations", "max_restarts", "stall_iterations"):
            value = getattr(self, name)
            if not (is_integer(value) and value >= 1):
                raise ConfigError(f"IKOptions.{name}", value, "an integer >= 1")
        for name in ("position_tolerance", "rotation_tolerance", "damping", "step", "stall_ratio"):
            value = getattr(self, name)
            if not (is_finite(value) and value > 0):
                raise ConfigError(f"IKOptions.{name}", value, "a positive number")
        for name, limit, unit in (
            ("position_tolerance", MAX_POSITION_TOLERANCE, "m"),
            ("rotation_tolerance", MAX_ROTATION_TOLERANCE, "rad"),
        ):
            if getattr(self, name) > limit:
                raise ConfigError(
                    f"IKOptions.{name}", getattr(self, name), f"at most {limit:g} {unit}"
                )


class IKSolver:
    """Palm-frame IK for one robot and one target pose.

    Args:
        robot: The robot.
        target: Palm frame target in the world frame.
        options: Solver settings.

    Attributes:
        calls: Single-restart solves run so far.
        iterations: Damped least-squares iterations run so far, over all restarts.
    """

    def __init__(self, robot: Robot, target: pin.SE3, options: IKOptions | None = None) -> None:
        if not isinstance(robot, Robot):
            raise ConfigError("robot", robot, "a Robot (load_robot)")
        if not isinstance(target, pin.SE3):
            raise ConfigError(
                "target", target, "a pinocchio.SE3 (pin.XYZQUATToSE3 converts [x, y, z, q])"
            )
        if options is not None and not isinstance(options, IKOptions):
            raise ConfigError("options", options, "IKOptions or None")
        self.robot = robot
        self.target = target
        self.options = options or IKOptions()
        self._model = robot.model
        self._data = robot.model.createData()
        self._frame = robot.palm_frame_id
        self._lower = robot.arm_lower
        self._upper = robot.arm_upper
        # Slices where the arm's indices run consecutively (every shipped robot): the
        # same values, without fancy indexing's cost in each iteration.
        self._arm = selector(robot.arm_idx)
        self._columns = selector(robot.arm_v_idx)
        self._q = robot.neutral()
        self._damping_eye = self.options.damping * np.eye(6)
        self.calls = 0
        self.iterations = 0

    def random_arm(self, rng: np.random.Generator) -> np.ndarray:
        """A restart point drawn uniformly inside the arm joint limits.

        Args:
            rng: The run's random generator.

        Returns:
            Arm joint values [rad or m], ``(dof,)``.
        """
        return rng.uniform(self._lower, self._upper)

    def error(self, arm: np.ndarray) -> tuple[float, float]:
        """Palm position error [m] and rotation error [rad] at an arm configuration.

        Args:
            arm: Arm joint values [rad or m].

        Returns:
            ``(position error [m], rotation error [rad])`` of the palm to :attr:`target`.
        """
        self._q[self.robot.arm_idx] = arm
        placement = self.robot.palm_placement(self._data, self._q)
        err = pin.log6(placement.actInv(self.target)).vector
        return float(np.linalg.norm(err[:3])), float(np.linalg.norm(err[3:]))

    def refine(self, arm: np.ndarray, target: pin.SE3 | None = None) -> np.ndarray | None:
        """Run damped least squares from ``arm`` towards ``target`` (default: the
        solver's :attr:`target`); the solution, or ``None`` if it stalls.

        Args:
            arm: Arm joint values to start from [rad or m].
            target: The palm pose to reach (world frame); default :attr:`target`.

        Returns:
            The converged arm joint values [rad or m], within the joint limits, or ``None``
            if the error stalls or the iterations run out.
        """
        target = self.target if target is None else target
        options = self.options
        model, data, q = self._model, self._data, self._q
        arm_idx, v_idx = self._arm, self._columns
        lower, upper = self._lower, self._upper
        x = np.clip(np.asarray(arm, dtype=float), lower, upper)
        self.calls += 1
        stall_ratio_sq = options.stall_ratio**2
        checkpoint = math.inf
        for iteration in range(options.max_iterations):
            self.iterations += 1
            q[arm_idx] = x
            pin.forwardKinematics(model, data, q)
            placement = pin.updateFramePlacement(model, data, self._frame)
            error_placement = placement.actInv(target)
            err = pin.log6(error_placement).vector
            if (
                err[0] ** 2 + err[1] ** 2 + err[2] ** 2 < options.position_tolerance**2
                and err[3] ** 2 + err[4] ** 2 + err[5] ** 2 < options.rotation_tolerance**2
            ):
                return x
            if iteration % options.stall_iterations == 0:
                error_sq = float(err @ err)
                if error_sq > stall_ratio_sq * checkpoint:
                    return None
                checkpoint = error_sq
            jacobian = pin.computeFrameJacobian(model, data, q, self._frame, pin.LOCAL)[:, v_idx]
            jacobian = -pin.Jlog6(error_placement.inverse()) @ jacobian
            step = -jacobian.T @ np.linalg.solve(jacobian @ jacobian.T + self._damping_eye, err)
            # np.clip's own value, at a fraction of its call overhead on 7 numbers.
            x = np.minimum(np.maximum(x + options.step * step, lower), upper)
        return None

    def palm_step(self, arm: np.ndarray, offset: np.ndarray) -> np.ndarray | None:
        """The arm configuration that moves the palm by ``offset`` [m, in the palm frame]
        with its orientation held: :meth:`refine` from ``arm`` towards the moved palm
        pose, or ``None`` where it stalls (for steps of centimetres it converges in a
        few iterations).

        Args:
            arm: Arm joint values to start from [rad or m].
            offset: The palm's displacement [m], in the palm frame, ``(3,)``.

        Returns:
            The arm joint values [rad or m] of the moved palm, or ``None``.
        """
        self._q[self.robot.arm_idx] = arm
        placement = self.robot.palm_placement(self._data, self._q)
        return self.refine(arm, placement * pin.SE3(np.eye(3), np.asarray(offset, dtype=float)))

    def solve(
        self, rng: np.random.Generator, seed_arm: np.ndarray | None = None
    ) -> np.ndarray | None:
        """Up to ``max_restarts`` refinements (the first from ``seed_arm`` if given).

        Args:
            rng: The run's random generator (restart points).
            seed_arm: Arm joint values [rad or m] to start the first refinement from.

        Returns:
            The first converged arm joint values [rad or m], or ``None`` if every restart
            stalled.
        """
        for attempt in range(self.options.max_restarts):
            start = seed_arm if attempt == 0 and seed_arm is not None else self.random_arm(rng)
            solution = self.refine(start)
            if solution is not None:
                return solution
        return None
