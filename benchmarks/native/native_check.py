"""The compiled coupled check (``_coupled_check``, built by ``build.sh`` beside this file),
set up from an :class:`~openup_ompl.state_check.StateChecker`.

A prototype measured by ``benchmarks/bench_native.py``; not part of the package.
"""

from __future__ import annotations

import importlib
import sys
from pathlib import Path
from typing import Any

import coal
import pinocchio as pin

from openup_ompl.collision import CollisionWorld
from openup_ompl.exceptions import ConfigError
from openup_ompl.state_check import StateChecker

#: Where ``build.sh`` leaves the extension.
HERE = Path(__file__).resolve().parent


def load() -> Any:
    """The compiled module, if it was built against the pinocchio and coal in use.

    The module works on the Python objects' C++ types in place (``pin.Data``, the Coal
    manager): built against another pinocchio it would read them with another layout,
    and pinocchio's library names carry no version that would stop it loading.

    Raises:
        ConfigError: It is not built (run ``bash benchmarks/native/build.sh``), or was
            built against other versions of pinocchio or coal.
    """
    if str(HERE) not in sys.path:
        sys.path.insert(0, str(HERE))
    try:
        module = importlib.import_module("_coupled_check")
    except ImportError as error:
        raise ConfigError(
            "benchmarks/native/_coupled_check", str(error), "built: bash benchmarks/native/build.sh"
        ) from None
    running = {"pinocchio": pin.__version__, "coal": coal.__version__}
    built = {name: module.built_with[name] for name in running}
    if built != running:
        raise ConfigError(
            "benchmarks/native/_coupled_check",
            f"built against {built}",
            f"built against the versions in use, {running}: bash benchmarks/native/build.sh",
        )
    return module


def law_table(checker: StateChecker) -> dict[str, Any]:
    """The law and Algorithm 1's distance as the compiled check takes them: the affine
    form of :class:`~openup_ompl.hand_law.HandLaw` and the checker's grasp and start."""
    law = checker.law
    grasp = checker.problem.grasp
    weighted = law.distance == "weighted"
    return {
        "mga": law.mga,
        "arrival": law.arrival.tolist(),
        "low_slope": law.low_slope.tolist(),
        "high": law.high.tolist(),
        "clip_low": law.clip_low,
        "lower": law.lower.tolist(),
        "upper": law.upper.tolist(),
        "fixed": None if law.fixed_clipped is None else law.fixed_clipped.tolist(),
        "goal": grasp.translation.tolist(),
        "goal_rotation_t": grasp.rotation.T.reshape(-1).tolist() if weighted else None,
        "rotation_weight": law.rotation_weight,
        "inv_start": 1.0 / checker.goal_distance.start_distance,
    }


def native_check(checker: StateChecker, world: CollisionWorld | None = None) -> Any:
    """A compiled check of single arm states at the checker's finest margin, on this
    thread's context of its finest world (the same Pinocchio data and Coal manager as
    :meth:`~openup_ompl.state_check.StateChecker.is_valid` uses).

    Args:
        checker: The Python checker whose law, grasp and world to use.
        world: Another world to check in (one of the checker's margins).

    Returns:
        A ``_coupled_check.CoupledCheck``: ``is_valid(arm)`` for any sequence of floats,
        ``distance`` (``d`` at the last state checked, ``inf`` for a fixed hand).
    """
    module = load()
    context = (checker.finest_world if world is None else world).context()
    robot = checker.robot
    return module.CoupledCheck(
        context.data,
        context.manager,
        robot.arm_idx.tolist(),
        robot.hand_idx.tolist(),
        robot.palm_frame_id,
        context.q.tolist(),
        law_table(checker),
    )
