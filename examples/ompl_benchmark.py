"""OMPL's own benchmarking tool on a grasp problem: IKBiRRT against RRTConnect.

Writes ``panda_can.log`` (OMPL's format) in the current directory; turn it into a database
for Planner Arena with ``ompl_benchmark_statistics panda_can.log``.
Run: ``python ompl_benchmark.py``.
"""

from ompl import geometric as og
from ompl import tools as ot

import openup_ompl as oo

problem = oo.load_scene(oo.default_scene_path())
setup = oo.GraspPlanningSetup(problem, u=0.3)

benchmark = ot.Benchmark(setup.simple_setup, "panda_can")
benchmark.addPlanner(oo.IKBiRRT(setup.space_information, oo.IKBiRRTOptions(seed=3)))
rrtconnect = og.RRTConnect(setup.space_information)
rrtconnect.setRange(0.4)
benchmark.addPlanner(rrtconnect)

request = ot.Request()
request.maxTime = 5.0  # [s] per run
request.runCount = 3
request.displayProgress = False
benchmark.benchmark(request)
benchmark.saveResultsToFile("panda_can.log")
print("results written to panda_can.log")
