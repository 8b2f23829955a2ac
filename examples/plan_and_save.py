"""Plan the Panda's can scene with the hand law and save the plan file.

Run from anywhere: ``python plan_and_save.py`` writes ``plan.json`` in the current
directory (replay it with ``openup-ompl show plan.json`` or ``openup-ompl execute``).
"""

import openup_ompl as oo

problem = oo.load_scene(oo.default_scene_path())  # robot + scene + grasp + law
setup = oo.GraspPlanningSetup(problem, oo.PlanningOptions(u=0.3, simplify=True))
plan = setup.solve(time_limit=5.0, planner="ikbirrt", seed=1)

print(f"{plan.status} by {plan.planner} in {plan.solve_time_s * 1e3:.0f} ms")
print(f"{len(plan.path)} rows of {plan.path.shape[1]} joints (arm and hand)")
print("written to", plan.save("plan.json"))
