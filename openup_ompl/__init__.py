"""openup-ompl: reach-to-grasp planning under object-pose uncertainty, on OMPL.

The hand opens with the pose uncertainty ``u`` and with the palm's normalised distance to
the grasp (Huaman Quispe and Stilman, "Open Up!"); the arm is planned with OMPL, every
state checked with the hand the law gives, collisions by Coal through Pinocchio.
"""

import os

# Batched collision checks run on OpenMP threads; busy-waiting threads stall every batch
# when another process holds a core. Takes effect if pinocchio is not yet imported.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

from openup_ompl.exceptions import (
    ConfigError,
    FrameNotFound,
    InvalidProblem,
    JointNotFound,
    MissingExtra,
    NativeBuildError,
    NativeUnavailable,
    OpenUpError,
    PlanningFailed,
    RobotNotFound,
    SimulationDiverged,
    SweepFailed,
    UnreachableGrasp,
    VerifyFailed,
)
from openup_ompl.goal import GraspGoal, IKGoalRegion
from openup_ompl.grasp import (
    ClosingOptions,
    Contact,
    GraspResult,
    HandCloser,
    close_hand,
    enclosed,
    force_closure,
)
from openup_ompl.hand_law import GoalDistance, HandLaw, NormalizedDistance, open_hand
from openup_ompl.ik import IKOptions, IKSolver
from openup_ompl.plan import Plan, PlanFile, read_plan
from openup_ompl.planners import IKBiRRT, IKBiRRTOptions
from openup_ompl.planning import PLANNERS, GraspPlanningSetup, PlanningOptions
from openup_ompl.robot import Robot, available_robots, load_robot
from openup_ompl.scene import Problem, Shape, default_scene_path, demo_scene_path, load_scene
from openup_ompl.validity import (
    DEFAULT_RESOLUTION,
    CoupledChecker,
    CoupledMotionValidator,
    CoupledValidityChecker,
)

__version__ = "0.1.0"

#: Names imported on first use (PEP 562): the experiment pulls in the executor and the
#: figures, which planning alone does not need and which would slow every command's start.
_LAZY = {
    "RobustnessOptions": "openup_ompl.robustness",
    "RobustnessResult": "openup_ompl.robustness",
    "run_robustness": "openup_ompl.robustness",
}


#: Submodules that ``import openup_ompl`` no longer imports itself, still reachable as
#: ``openup_ompl.robustness`` after the package alone was imported (as before).
_LAZY_MODULES = {"robustness"}


def __getattr__(name: str) -> object:
    if name in _LAZY or name in _LAZY_MODULES:
        import importlib

        module = importlib.import_module(_LAZY.get(name, f"openup_ompl.{name}"))
        value = module if name in _LAZY_MODULES else getattr(module, name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'openup_ompl' has no attribute {name!r}")


__all__ = [
    "DEFAULT_RESOLUTION",
    "PLANNERS",
    "ClosingOptions",
    "ConfigError",
    "Contact",
    "CoupledChecker",
    "CoupledMotionValidator",
    "CoupledValidityChecker",
    "FrameNotFound",
    "GoalDistance",
    "GraspGoal",
    "GraspPlanningSetup",
    "GraspResult",
    "HandCloser",
    "HandLaw",
    "IKBiRRT",
    "IKBiRRTOptions",
    "IKGoalRegion",
    "IKOptions",
    "IKSolver",
    "InvalidProblem",
    "JointNotFound",
    "MissingExtra",
    "NativeBuildError",
    "NativeUnavailable",
    "NormalizedDistance",
    "OpenUpError",
    "Plan",
    "PlanFile",
    "PlanningFailed",
    "PlanningOptions",
    "Problem",
    "Robot",
    "RobotNotFound",
    "RobustnessOptions",
    "RobustnessResult",
    "Shape",
    "SimulationDiverged",
    "SweepFailed",
    "UnreachableGrasp",
    "VerifyFailed",
    "__version__",
    "available_robots",
    "close_hand",
    "default_scene_path",
    "demo_scene_path",
    "enclosed",
    "force_closure",
    "load_robot",
    "load_scene",
    "open_hand",
    "read_plan",
    "run_robustness",
]
