"""The closed loop by hand: perceive the object, plan for the estimate, execute against the
truth.

A simulated depth camera looks at the can; a superquadric fit gives its pose and
covariance, and the covariance gives ``u``. The plan is made for the estimated object (the
grasp pose moves with it) and executed in physics against the object where it truly is:
the offset passed to ``execute_plan`` is the true pose relative to the estimate.
Run: ``python perceive_plan_execute.py``.
"""

import numpy as np
from scipy.spatial.transform import Rotation

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

# The plan believes the object is at the estimate; the world has it at the true pose.
dx, dy = truth.object.pose[:2] - seen.pose[:2]
yaw_true = Rotation.from_quat(truth.object.pose[3:]).as_euler("xyz")[2]
yaw_seen = Rotation.from_quat(seen.pose[3:]).as_euler("xyz")[2]
dyaw = float(np.angle(np.exp(1j * (yaw_true - yaw_seen))))
record = execute_plan(plan, (float(dx), float(dy), dyaw), frames=False)
print(record.verdict)
