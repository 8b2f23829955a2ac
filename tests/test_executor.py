"""The sweep executor: local pool and Dask give the same records; no run lost or doubled."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from openup_ompl.benchmark import default_problems_dir, make_tasks
from openup_ompl.exceptions import ConfigError
from openup_ompl.executor import SweepFailed, Task, load_records, run_tasks, shard_path

pytestmark = pytest.mark.slow  # subprocesses, sweeps or OMPL benchmark runs

FUNCTION = "openup_ompl.executor:selfcheck_task"


def _tasks(n: int, **kwargs: object) -> list[Task]:
    return [
        Task(key=f"t{i}", function=FUNCTION, kwargs=dict(kwargs), seed=10 + i) for i in range(n)
    ]


def _deterministic(records: list[dict]) -> list[dict]:
    return [{k: v for k, v in r.items() if k != "pid"} for r in records]


def _local_cluster():  # type: ignore[no-untyped-def]
    """A Dask cluster of two worker processes on loopback."""
    distributed = pytest.importorskip("dask.distributed")
    return distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None
    )


def test_pool_records_are_seeded_per_task(tmp_path: Path) -> None:
    """Each task gets its own process, so a seed gives the same OMPL draws in any order."""
    tasks = _tasks(4)
    run_tasks(tasks, tmp_path / "a", workers=2, quiet=True)
    run_tasks(list(reversed(tasks)), tmp_path / "b", workers=1, quiet=True)
    a = load_records(tasks, tmp_path / "a")
    b = load_records(tasks, tmp_path / "b")
    assert len(a) == 4 and _deterministic(a) == _deterministic(b)
    assert len({r["pid"] for r in a}) == 4
    assert len({tuple(r["draws"]) for r in a}) == 4


def test_seed_zero_draws_as_one_without_a_warning(tmp_path: Path) -> None:
    """OMPL refuses seed 0 and draws as from 1: a task seeded 0 gives seed 1's draws, and
    its process writes nothing on stderr."""
    draws = {}
    for seed in (0, 1):
        task = Task(key=f"s{seed}", function=FUNCTION, seed=seed)
        done = subprocess.run(
            [sys.executable, "-m", "openup_ompl.executor", str(tmp_path)],
            input=task.to_json(), capture_output=True, text=True, timeout=120, check=False,
        )  # fmt: skip
        assert done.returncode == 0 and done.stderr == "", done.stderr
        draws[seed] = json.loads(shard_path(tmp_path, task.key).read_text())["draws"]
    assert draws[0] == draws[1]


def test_dask_and_pool_give_the_same_records(tmp_path: Path) -> None:
    """A Dask LocalCluster on loopback and the local pool give identical records."""
    tasks = _tasks(4)
    run_tasks(tasks, tmp_path / "pool", workers=2, quiet=True)
    with _local_cluster() as cluster:
        ran = run_tasks(tasks, tmp_path / "dask", scheduler=cluster.scheduler_address, quiet=True)
    assert sorted(ran) == sorted(t.key for t in tasks)
    pool = load_records(tasks, tmp_path / "pool")
    dask = load_records(tasks, tmp_path / "dask")
    assert _deterministic(pool) == _deterministic(dask)


@pytest.mark.parametrize("use_dask", [False, True])
def test_killed_run_loses_no_run(tmp_path: Path, use_dask: bool) -> None:
    """A task whose process is killed the first time is retried; one shard per task."""
    tasks = _tasks(3)
    marker = tmp_path / "killed-once"
    tasks[1] = Task(key="t1", function=FUNCTION, kwargs={"marker": str(marker)}, seed=11)
    shards = tmp_path / "shards"
    if use_dask:
        with _local_cluster() as cluster:
            run_tasks(tasks, shards, scheduler=cluster.scheduler_address, quiet=True)
    else:
        run_tasks(tasks, shards, workers=2, quiet=True)
    assert marker.exists()  # the first attempt really died
    killed_pid = int(marker.read_text())
    records = load_records(tasks, shards)
    assert [r["key"] for r in records] == ["t0", "t1", "t2"]
    assert records[1]["pid"] != killed_pid
    assert sorted(p.name for p in shards.iterdir()) == ["t0.json", "t1.json", "t2.json"]


def test_killed_dask_worker_loses_no_run(tmp_path: Path) -> None:
    """A Dask worker process killed mid-task (SIGKILL) has its task rerun elsewhere; every
    task lands exactly once."""
    marker = tmp_path / "worker-killed"
    tasks = _tasks(4)
    tasks[2] = Task(
        key="t2", function=FUNCTION, kwargs={"marker": str(marker), "kill": "worker"}, seed=12
    )
    shards = tmp_path / "shards"
    with _local_cluster() as cluster:
        run_tasks(tasks, shards, scheduler=cluster.scheduler_address, quiet=True)
    worker_pid = int(marker.read_text())
    with pytest.raises(ProcessLookupError):
        os.kill(worker_pid, 0)  # that worker is gone
    records = load_records(tasks, shards)
    assert [r["key"] for r in records] == ["t0", "t1", "t2", "t3"]
    assert sorted(p.name for p in shards.iterdir()) == ["t0.json", "t1.json", "t2.json", "t3.json"]


def test_dask_and_pool_give_the_same_benchmark_records(tmp_path: Path) -> None:
    """Real benchmark runs (IKBiRRT and RRTConnect, seeded) give the same counters and
    results through a Dask LocalCluster as through the local pool."""
    problem = default_problems_dir() / "table_pick.toml"
    tasks = make_tasks([problem], ["ikbirrt", "rrtconnect"], runs=1, time_limit=5.0)
    run_tasks(tasks, tmp_path / "pool", workers=2, quiet=True)
    with _local_cluster() as cluster:
        run_tasks(tasks, tmp_path / "dask", scheduler=cluster.scheduler_address, quiet=True)
    fields = ("key", "seed", "solved", "length", "ik_calls", "state_checks", "motion_checks")

    def same(records: list[dict]) -> list[tuple]:
        return [tuple(r[f] for f in fields) for r in records]

    pool, dask = load_records(tasks, tmp_path / "pool"), load_records(tasks, tmp_path / "dask")
    assert len(pool) == 2 and all(r["solved"] for r in pool)
    assert same(pool) == same(dask)


def test_dask_and_pool_give_the_same_robustness_records(tmp_path: Path) -> None:
    """The robustness sweep goes through the same executor: a Dask LocalCluster and the
    local pool give the same trials (plans seeded, every perturbation re-run)."""
    from openup_ompl.robustness import RobustnessOptions, run_robustness

    options = RobustnessOptions(us=(0.3,), deltas=(0.0, 0.01), seeds=2)
    pool = run_robustness(None, options, tmp_path / "pool", workers=2, quiet=True)
    with _local_cluster() as cluster:
        dask = run_robustness(
            None, options, tmp_path / "dask", scheduler=cluster.scheduler_address, quiet=True
        )
    assert len(pool.records) == 2 and all(r["planned"] for r in pool.records)
    assert [r["trials"] for r in pool.records] == [r["trials"] for r in dask.records]
    assert [r["rows"] for r in pool.records] == [r["rows"] for r in dask.records]
    assert pool.rows == dask.rows


def test_rerun_skips_finished_runs(tmp_path: Path) -> None:
    """A second run of the same sweep runs nothing and leaves the shards untouched."""
    tasks = _tasks(2)
    assert sorted(run_tasks(tasks, tmp_path, workers=2, quiet=True)) == ["t0", "t1"]
    before = {t.key: shard_path(tmp_path, t.key).read_text() for t in tasks}
    more = [*tasks, Task(key="t9", function=FUNCTION, seed=99)]
    assert run_tasks(more, tmp_path, workers=2, quiet=True) == ["t9"]
    assert {t.key: shard_path(tmp_path, t.key).read_text() for t in tasks} == before
    assert json.loads(shard_path(tmp_path, "t9").read_text())["seed"] == 99


def test_failing_task_raises_after_retries(tmp_path: Path) -> None:
    """A task that fails every attempt raises SweepFailed naming it; the others finish."""
    tasks = [*_tasks(1), Task(key="bad", function=FUNCTION, kwargs={"fail": True})]
    with pytest.raises(SweepFailed) as caught:
        run_tasks(tasks, tmp_path, workers=2, retries=1, quiet=True)
    assert list(caught.value.failures) == ["bad"]
    assert shard_path(tmp_path, "t0").exists() and not shard_path(tmp_path, "bad").exists()


@pytest.mark.parametrize(
    "call",
    [
        lambda p: run_tasks([*_tasks(1), *_tasks(1)], p),
        lambda p: run_tasks(_tasks(1), p, workers=0),
        lambda p: run_tasks(_tasks(1), p, retries=-1),
        lambda p: Task(key="a/b", function=FUNCTION),
        lambda p: Task(key="a", function="no_colon"),
    ],
)
def test_bad_sweep_input_raises_config_error(tmp_path: Path, call) -> None:  # type: ignore[no-untyped-def]
    """Duplicate keys, bad worker or retry counts and bad task fields are ConfigErrors."""
    with pytest.raises(ConfigError):
        call(tmp_path)
