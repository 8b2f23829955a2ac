"""Execute a plan in physics (MuJoCo) against an object that is not where it was planned.

Plans the Panda's can scene, then runs the plan with the can 1 cm off along +y (the
fingers' travel): reach, close, lift 10 cm, hold 2 s. Writes ``execution.json`` (replay
it with ``openup-ompl show execution.json``). Run: ``python execute_displaced.py``.
"""

import openup_ompl as oo
from openup_ompl.physics import PhysicsOptions, execute_plan, write_execution

problem = oo.load_scene(oo.default_scene_path())
plan = oo.GraspPlanningSetup(problem, u=0.3).solve(time_limit=5.0, seed=1)

for offset in [(0.0, 0.0, 0.0), (0.0, 0.01, 0.0)]:  # (dx [m], dy [m], yaw [rad]), world frame
    record = execute_plan(plan, offset, options=PhysicsOptions())
    print(f"offset {offset}: {record.verdict}")

print("success:", record.success, "| cause:", record.cause)
print("written to", write_execution(record, "."))  # ./execution.json
