"""The coupled checks in an OMPL pipeline of your own: your SimpleSetup, your planner.

Every piece the package's ``GraspPlanningSetup`` assembles, built by hand: the arm's state
space, the coupled state and motion checks (hand set by the law at every state), the IK
goal region, and OMPL's ``RRTConnect``. Run: ``python own_simple_setup.py``.
"""

import numpy as np
from ompl import geometric as og

import openup_ompl as oo
from openup_ompl.planning import arm_state_space

problem = oo.load_scene(oo.default_scene_path())
robot = problem.robot

# 1. OMPL's state space: the arm joints, bounded by their limits.
space = arm_state_space(robot)
ss = og.SimpleSetup(space)
si = ss.getSpaceInformation()

# 2. The coupled checks: forward kinematics -> d -> hand from the law -> Coal collision.
checker = oo.CoupledChecker(problem)  # the scene's law; resolution 6 mm, exact motions
ss.setStateValidityChecker(oo.CoupledValidityChecker(si, checker))
si.setMotionValidator(oo.CoupledMotionValidator(si, checker))

# 3. The start, and the goal: IK solutions of the grasp pose, backed off 10 cm (pregrasp).
start = si.allocState()
start[0 : robot.arm_idx.size] = problem.start.tolist()
ss.setStartState(start)
ik = oo.IKSolver(robot, problem.grasp)  # damped least squares on Pinocchio
goal = oo.GraspGoal(checker, ik, np.random.default_rng(1))
region = oo.IKGoalRegion(si, goal, max_samples=25, pregrasp=0.1)
ss.setGoal(region)

# 4. Any OMPL planner that takes sampleable goals.
planner = og.RRTConnect(si)
planner.setRange(0.4)  # [rad]: long coupled motions mostly end in collision
ss.setPlanner(planner)
status = ss.solve(5.0)
print("OMPL status:", status)
assert ss.haveExactSolutionPath(), "no plan within 5 s"

# 5. The path ends at a pregrasp state: append the certified approach to the grasp.
path = ss.getSolutionPath()
states = np.array(
    [
        [path.getState(i)[j] for j in range(space.getDimension())]
        for i in range(path.getStateCount())
    ]
)
approach = region.approach(states[-1].tolist())
arm_path = np.vstack([states, approach])
print(f"{len(states)} waypoints + {len(approach)} approach states")
print("palm to grasp at the end [m]:", round(goal.task_error(arm_path[-1]), 5))
print("every waypoint valid with the law's hand:", all(checker.is_valid(a) for a in arm_path))
