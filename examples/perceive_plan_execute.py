"""The closed loop by hand: perceive the object, plan for the estimate, execute against the
truth.

A simulated depth camera looks at the can; a superquadric fit gives its pose and
covariance, and the covariance gives ``u``. The plan is made for the estimated object (the
grasp pose moves with it) and executed in physics against the object where it truly is:
``execute_plan(plan, truth=...)`` puts the true scene's object in the plan's world.
Run: ``python perceive_plan_execute.py``.
"""

import numpy as np

import openup_ompl as oo
from openup_ompl.perception import NoiseOptions, at_estimate, perceive
from openup_ompl.physics import execute_plan

truth = oo.load_scene(oo.demo_scene_path())
seen = perceive(truth, noise=NoiseOptions(scale=1.0), rng=np.random.default_rng(1))
print(
    f"estimated u = {seen.u:.3f}; position error [mm]:",
    np.round((seen.pose[:3] - truth.object.pose[:3]) * 1e3, 1),
)

estimate = at_estimate(truth, seen.pose)  # the scene with the object (and grasp) moved
plan = oo.GraspPlanningSetup(estimate, u=seen.u).solve(time_limit=5.0, seed=1)

# The plan believes the object is at the estimate; the world has it at the true pose
# (`truth`: the true scene's object replaces the plan's, as `execute --truth` does).
record = execute_plan(plan, truth=truth, frames=False)
print(record.verdict)
