"""Physics execution of plans in MuJoCo: the object free, the hand closing, a lift test.

:func:`execute_plan` runs a plan (reach, close, squeeze, lift, hold) and returns its
:class:`ExecutionRecord`; :mod:`~openup_ompl.physics.sweep` runs the paper's experiment
that way (``openup-ompl robustness --execute physics``). Modules: ``options`` (the
settings), ``world`` (the MuJoCo model: robot, object, neighbours, contacts), ``shapes``
(scene shapes as geoms), ``inputs`` (what a rollout takes of a plan), ``trajectory``
(timing), ``targets`` (the closed hand, the lift), ``monitor`` (the step and what it
watches), ``phases`` (the six phases), ``verdict``, ``rollout`` (:class:`Rollout`),
``record`` (the file).
"""

from openup_ompl.physics.options import PHASE_MAX, PhysicsOptions
from openup_ompl.physics.record import ExecutionRecord, read_execution, write_execution
from openup_ompl.physics.rollout import Rollout, execute_plan
from openup_ompl.physics.world import World, build_world

__all__ = [
    "PHASE_MAX",
    "ExecutionRecord",
    "PhysicsOptions",
    "Rollout",
    "World",
    "build_world",
    "execute_plan",
    "read_execution",
    "write_execution",
]
