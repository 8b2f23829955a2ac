"""The planners run inside OMPL's own benchmarking tool and write its log."""

from __future__ import annotations

from pathlib import Path

import pytest
from ompl import geometric as og
from ompl import tools as ot
from ompl import util as ompl_util

import openup_ompl as oo

pytestmark = pytest.mark.slow  # subprocesses, sweeps or OMPL benchmark runs

ompl_util.setLogLevel(ompl_util.LOG_ERROR)


def test_ompl_benchmark_runs_ikbirrt_and_rrtconnect(tmp_path: Path) -> None:
    """ompl.tools.Benchmark runs IKBiRRT and RRTConnect on the IK goal, every run solved."""
    setup = oo.GraspPlanningSetup(oo.load_scene(oo.default_scene_path()))
    si = setup.space_information
    planner = oo.IKBiRRT(si, oo.IKBiRRTOptions(seed=3))
    benchmark = ot.Benchmark(setup.simple_setup, "default_scene")
    benchmark.addPlanner(planner)
    benchmark.addPlanner(og.RRTConnect(si))
    request = ot.Request()
    request.maxTime = 5.0
    request.runCount = 2
    request.displayProgress = False
    request.saveConsoleOutput = False
    benchmark.benchmark(request)
    log = tmp_path / "bench.log"
    assert benchmark.saveResultsToFile(str(log))
    experiment = benchmark.getRecordedExperimentData()
    names = [p.name for p in experiment.planners]
    assert names == ["geometric_IKBiRRT", "geometric_RRTConnect"]
    for planner_runs in experiment.planners:
        runs = [run.to_dict() for run in planner_runs.runs]
        assert len(runs) == 2
        assert all(run["solved BOOLEAN"] in (1, "1", True) for run in runs)
    text = log.read_text()
    assert "geometric_IKBiRRT" in text and "geometric_RRTConnect" in text
    segments = [
        int(run.to_dict()["solution segments INTEGER"])
        for p in experiment.planners
        for run in p.runs
    ]
    assert all(count >= 1 for count in segments)  # each run recorded its solution path
