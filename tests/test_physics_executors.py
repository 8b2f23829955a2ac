"""Physics rollouts give the same records through the local process pool and a Dask
cluster (:mod:`openup_ompl.executor`): a small fixed set of the throughput set's trials
(``tests/data/physics_trials.json``) in two tasks, one per worker."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

pytest.importorskip("mujoco")
#: Six task processes and a Dask cluster: 54 s on this machine's two cores under a load
#: of 6, four minutes under 11.
pytestmark = pytest.mark.slow
sys.path.insert(0, str(Path(__file__).resolve().parent))

import physics_regression as regression  # noqa: E402

from openup_ompl.executor import Task, load_records, run_tasks  # noqa: E402

#: Per task, {case index: trial indices}: held, pushed away and dropped Panda cans and
#: the Allegro's held and slipped ones; the LWA3-SDH's held, untouched and not-lifted
#: cans and the bottle beside its movable cup held and missed.
TASKS = [{"0": [0, 7, 13], "3": [0, 17]}, {"2": [0, 12, 14], "4": [0, 9]}]


def _tasks() -> list[Task]:
    return [
        Task(key=f"part{k}", function="physics_regression:replay", kwargs={"cases": cases})
        for k, cases in enumerate(TASKS)
    ]


def test_pool_and_dask_give_the_same_rollout_records(tmp_path, monkeypatch):
    """The ten trials run through the pool (two workers) and a Dask LocalCluster (two
    worker processes) give identical execution records, whose verdicts are the recorded
    ones."""
    distributed = pytest.importorskip(
        "dask.distributed", reason="Dask is the optional extra openup-ompl[distributed]"
    )
    # The task processes import physics_regression from here (the Dask workers inherit
    # the environment when the cluster starts, their task processes from them).
    here = str(Path(__file__).resolve().parent)
    monkeypatch.setenv(
        "PYTHONPATH", os.pathsep.join(filter(None, [here, os.environ.get("PYTHONPATH")]))
    )
    tasks = _tasks()
    run_tasks(tasks, tmp_path / "pool", workers=2, quiet=True)
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
        dashboard_address=None,
    ) as cluster:  # fmt: skip
        run_tasks(tasks, tmp_path / "dask", scheduler=cluster.scheduler_address, quiet=True)
    pool, dask = load_records(tasks, tmp_path / "pool"), load_records(tasks, tmp_path / "dask")
    assert [r["records"] for r in pool] == [r["records"] for r in dask]
    stored = regression.load(regression.TRIALS)
    verdicts = [(r["success"], r["cause"]) for shard in pool for r in shard["records"]]
    expected = [
        (stored[int(i)]["trials"][k]["success"], stored[int(i)]["trials"][k]["cause"])
        for cases in TASKS for i, ks in cases.items() for k in ks
    ]  # fmt: skip
    assert len(verdicts) == 10 and verdicts == expected
    assert {cause for _, cause in expected} == {None, "no contact", "dropped", "not lifted",
                                                 "slipped"}  # fmt: skip
