"""One executor for sweeps of independent runs: a local pool, or a Dask cluster.

A sweep is a list of :class:`Task`: a small JSON-able description (a stable ``key``, the
``"module:function"`` to call, its keyword arguments and a ``seed``). Every task runs in a
fresh Python process (``python -m openup_ompl.executor``), because OMPL's random generator
can only be seeded before any OMPL object exists in a process: the same seed then gives
the same record whichever executor ran it. The function rebuilds everything it needs from
files (OMPL objects do not pickle) and returns a JSON-able dict, the run's record.

Each record lands in its own shard file ``<shards>/<key>.json``, written atomically
(temporary file + ``os.replace``), so:

- a rerun skips every task whose shard exists (finished runs are never redone);
- a run whose process dies (killed, crashed) leaves no shard and is retried, up to
  ``retries`` times; a run is counted once because its shard is keyed by the task key;
- :func:`load_records` merges the shards into one list, in task order.

Executors: :func:`run_tasks` with ``scheduler=None`` runs ``workers`` task processes at a
time on this machine; with a scheduler address (``tcp://host:8786``) it submits the tasks
to a Dask distributed cluster (``pip install "openup-ompl[distributed]"``), where each
Dask task launches the task process on its worker and Dask retries a task whose worker
died.
"""

from __future__ import annotations

import hashlib
import importlib
import json
import os
import subprocess
import sys
import time
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ThreadPoolExecutor, wait
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from openup_ompl._io import check_dir, make_dir, write_atomic
from openup_ompl._toml import is_integer
from openup_ompl.exceptions import ConfigError, MissingExtra, SweepFailed

__all__ = [
    "SweepFailed",
    "Task",
    "load_records",
    "run_task_process",
    "reseed_ompl",
    "run_tasks",
    "seed_ompl",
    "selfcheck_task",
    "settings_digest",
    "shard_path",
]


#: Seeds are below this (OMPL's and numpy's generators take them as 32-bit integers).
SEED_LIMIT = 2**31


def check_generator_seed(seed: int, where: str = "seed") -> int:
    """Check a seed of numpy's and OMPL's generators.

    Args:
        seed: The seed.
        where: The name errors give it.
    Returns:
        ``seed`` as a Python ``int``.
    Raises:
        ConfigError: ``seed`` is not an integer in ``[0, SEED_LIMIT)``.
    """
    if not (is_integer(seed) and 0 <= seed < SEED_LIMIT):
        raise ConfigError(where, seed, "an integer seed in [0, 2^31)")
    return int(seed)


def check_seeds(first: int, count: int, most: int, where: str) -> None:
    """Refuse a run of seeds ``first, ..., first + count - 1`` (``where`` names ``count``)
    that is empty, longer than ``most`` or reaches :data:`SEED_LIMIT`.

    Args:
        first, count: The first seed and the number of seeds.
        most: The largest ``count`` accepted.
        where: The name errors give ``count``.
    Raises:
        ConfigError: Naming ``where``, ``seed`` or their sum.
    """
    if not (is_integer(count) and 1 <= count <= most):
        raise ConfigError(where, count, f"an integer in [1, {most}]")
    check_generator_seed(first)
    if first + count - 1 >= SEED_LIMIT:
        raise ConfigError(
            f"seed + {where} - 1",
            first + count - 1,
            f"a last seed below 2^31 (seed {first} with {where} {count})",
        )


#: The example an error about a scheduler address gives.
SCHEDULER_EXAMPLE = "a Dask scheduler address such as tcp://host:8786"
#: How long [s] a sweep waits for its Dask scheduler to answer (Dask's ``Client(timeout=)``).
CONNECT_TIMEOUT = 30.0


def check_scheduler(address: str, where: str = "scheduler") -> str:
    """``address`` if it is a Dask scheduler address, ``[scheme://]host:port`` (checked
    with Dask's own parsers; without Dask installed, any non-empty string: the run then
    says the extra is missing). Dask takes no default port (``bogus`` failed in its
    connection code with ``missing port number``).

    Args:
        address: The scheduler's address, e.g. ``tcp://host:8786``.
        where: The name errors give it.
    Returns:
        ``address`` unchanged.
    Raises:
        ConfigError: Not such an address, naming ``where``, the address and why.
    """
    if not isinstance(address, str) or not address.strip():
        raise ConfigError(where, address, SCHEDULER_EXAMPLE)
    try:
        from distributed.comm import registry
        from distributed.comm.addressing import parse_address, parse_host_port
    except ImportError:
        return address
    try:
        scheme, location = parse_address(address)
        registry.get_backend(scheme)  # loads one installed by an entry point, or says why not
        if scheme != "inproc":
            host, port = parse_host_port(location)
            if not host or not 0 < port < 2**16:
                raise ValueError(f"expected a host and a port in [1, 65535] in {location!r}")
    except ValueError as error:
        raise ConfigError(where, address, f"{SCHEDULER_EXAMPLE} ({error})") from None
    return address


def seed_ompl(seed: int) -> None:
    """Seed OMPL's process-wide generator (before any OMPL object exists in the process).

    OMPL refuses 0 with a two-line warning on stderr and draws as from 1: 0 is given 1
    here, the same draws without the warning.

    Args:
        seed: The seed, an integer in ``[0, 2^31)``.
    """
    from ompl import util as ompl_util

    ompl_util.RNG.setSeed(max(int(seed), 1))


def reseed_ompl(seed: int) -> None:
    """Restart OMPL's process-wide seed generator in a process that has already sampled,
    so that the OMPL objects made next (a plan's planner, samplers and path simplifier)
    draw as they would in a fresh process seeded with ``seed``: a plan then depends on its
    own seed, not on the plans made before it in the process. OMPL's complaint that
    sampling has started (it assumes objects made before the call) is silenced.

    Args:
        seed: The seed, an integer in ``[0, 2^31)``.
    """
    from ompl import util as ompl_util

    level = ompl_util.getLogLevel()
    ompl_util.setLogLevel(ompl_util.LOG_NONE)
    try:
        seed_ompl(seed)
    finally:
        ompl_util.setLogLevel(level)


@dataclass(frozen=True)
class Task:
    """One independent run of a sweep.

    Attributes:
        key: Stable identifier, unique in the sweep; names the shard file (letters,
            digits, ``-``, ``_`` and ``.`` only).
        function: ``"module:function"`` called as ``function(seed=seed, **kwargs)`` in a
            fresh process; returns a JSON-able dict.
        kwargs: JSON-able keyword arguments (paths, names, numbers).
        seed: Seeds OMPL's process-wide generator before the function runs, and is passed
            to it.
    """

    key: str
    function: str
    kwargs: dict[str, Any] = field(default_factory=dict)
    seed: int = 0

    def __post_init__(self) -> None:
        if not self.key or not all(ch.isalnum() or ch in "-_." for ch in self.key):
            raise ConfigError("task key", self.key, "letters, digits, '-', '_' or '.'")
        if ":" not in self.function:
            raise ConfigError("task function", self.function, "'module:function'")

    def to_json(self) -> str:
        """The task as JSON (its key, function, keyword arguments and seed): what
        :func:`run_task_process` takes.

        Returns:
            The JSON text.
        """
        return json.dumps(asdict(self), sort_keys=True)


def settings_digest(settings: dict[str, Any], files: Iterable[Path]) -> str:
    """A short digest of a sweep's ``settings`` (JSON values) and of the contents of the
    ``files`` its runs read, for its task keys: a rerun into the same shards reuses a
    finished run only when neither changed (a can's radius edited in the scene file, a
    joint limit in the URDF, another time limit give other keys).

    Args:
        settings: The sweep's settings, JSON values.
        files: The files its runs read.

    Returns:
        A hexadecimal digest (10 characters).
    """
    contents = [hashlib.sha1(Path(file).read_bytes()).hexdigest() for file in files]
    keyed = json.dumps({**settings, "contents": contents}, sort_keys=True)
    return hashlib.sha1(keyed.encode()).hexdigest()[:10]


def shard_path(shards: Path, key: str) -> Path:
    """The shard file of the task ``key``.

    Args:
        shards: Directory of the shard files.
        key: The task's key.

    Returns:
        ``shards / <key>.json``.
    """
    return Path(shards) / f"{key}.json"


def _execute(task: Task, shards: Path) -> dict[str, Any]:
    """Inside the task process: seed OMPL, call the function, write the shard."""
    from ompl import util as ompl_util

    seed_ompl(task.seed)
    ompl_util.setLogLevel(ompl_util.LOG_ERROR)
    module, _, name = task.function.partition(":")
    function: Callable[..., dict[str, Any]] = getattr(importlib.import_module(module), name)
    record = dict(function(seed=task.seed, **task.kwargs))
    record.setdefault("key", task.key)
    write_atomic(shard_path(shards, task.key), json.dumps(record, sort_keys=True) + "\n")
    return record


def run_task_process(task_json: str, shards: str, timeout: float | None = None) -> str:
    """Run one task in a fresh Python process; returns its key once its shard exists.

    This is what each executor calls (a Dask worker included): it is a plain function of
    strings, so it pickles. A process that dies leaves no shard and raises
    ``RuntimeError``, which makes the executor retry the task.

    Args:
        task_json: The task (:meth:`Task.to_json`).
        shards: Directory of the shard files.
        timeout: Wall-clock limit [s] of the process (``None``: none).

    Returns:
        The task's key.
    """
    task = Task(**json.loads(task_json))
    target = shard_path(Path(shards), task.key)
    if target.exists():
        return task.key
    done = subprocess.run(
        [sys.executable, "-m", "openup_ompl.executor", str(shards)],
        input=task_json,
        capture_output=True,
        text=True,
        timeout=timeout,
    )
    if done.returncode != 0 or not target.exists():
        tail = done.stderr.strip().splitlines()[-1:] or [f"exit status {done.returncode}"]
        raise RuntimeError(f"task {task.key} process exited {done.returncode}: {tail[0]}")
    return task.key


class _Progress:
    """Runs done on stderr: one updating line on a terminal, else a line per tenth."""

    def __init__(self, total: int, quiet: bool) -> None:
        self.total = total
        self.done = 0
        self.on = not quiet and total > 0
        self.tty = sys.stderr.isatty()
        self.started = time.monotonic()

    def step(self, note: str = "") -> None:
        self.done += 1
        if not self.on:
            return
        elapsed = time.monotonic() - self.started
        left = elapsed / self.done * (self.total - self.done)
        line = f"{self.done}/{self.total} runs, {elapsed:.0f} s, about {left:.0f} s left {note}"
        if self.tty:
            end = "\n" if self.done == self.total else ""
            print(f"\r{line:<78}", end=end, file=sys.stderr, flush=True)
        elif self.done == self.total or self.done % max(1, self.total // 10) == 0:
            print(line, file=sys.stderr, flush=True)


def _check_keys(tasks: Sequence[Task]) -> None:
    seen: set[str] = set()
    for task in tasks:
        if task.key in seen:
            raise ConfigError("task key", task.key, "keys unique in the sweep")
        seen.add(task.key)


def run_tasks(
    tasks: Sequence[Task],
    shards: str | Path,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    retries: int = 2,
    timeout: float | None = None,
    quiet: bool = False,
) -> list[str]:
    """Run the tasks whose shard is missing; returns the keys that ran now.

    Args:
        tasks: The sweep (keys unique).
        shards: Directory of the shard files.
        workers: Task processes at a time on this machine (default: the usable cores).
            Ignored with ``scheduler``.
        scheduler: Address of a Dask distributed scheduler; ``None`` runs locally.
        retries: Attempts after the first for a task whose process died or failed.
        timeout: Wall-clock limit [s] per task process (``None``: none).
        quiet: No progress on stderr (else one updating line on a terminal, a line per
            tenth of the runs otherwise).

    Returns:
        The keys of the tasks that ran now (those already finished are skipped).

    Raises:
        ConfigError: Duplicate keys, ``workers`` below 1, ``retries`` below 0, or a
            ``scheduler`` that is not an address (:func:`check_scheduler`) or that Dask's
            client refuses.
        SweepFailed: Some task failed on every attempt (the others' shards are kept).
    """
    _check_keys(tasks)
    if scheduler is not None:
        check_scheduler(scheduler)
    if workers is not None and not (is_integer(workers) and workers >= 1):
        raise ConfigError("workers", workers, "an integer >= 1")
    if not (is_integer(retries) and retries >= 0):
        raise ConfigError("retries", retries, "0 or more")
    shards = Path(shards)
    check_dir(shards)
    todo = [t for t in tasks if not shard_path(shards, t.key).exists()]
    if not todo:
        return []
    progress = _Progress(len(todo), quiet)
    # The shards directory is made once the tasks can run: a scheduler that cannot be
    # reached leaves none behind.
    if scheduler is not None:
        failures = _run_dask(todo, shards, scheduler, retries, timeout, progress)
    else:
        count = workers or len(os.sched_getaffinity(0))
        make_dir(shards)
        failures = _run_local(todo, shards, count, retries, timeout, progress)
    if failures:
        raise SweepFailed(failures)
    return [t.key for t in todo]


def _run_local(
    todo: Sequence[Task],
    shards: Path,
    workers: int,
    retries: int,
    timeout: float | None,
    progress: _Progress,
) -> dict[str, str]:
    # Threads only wait on the task processes, one fresh process per task: a killed
    # process loses its run alone, which is resubmitted here.
    failures: dict[str, str] = {}
    attempts = dict.fromkeys((t.key for t in todo), 0)
    with ThreadPoolExecutor(max_workers=workers) as pool:
        pending: dict[Future[str], Task] = {
            pool.submit(run_task_process, t.to_json(), str(shards), timeout): t for t in todo
        }
        while pending:
            finished, _ = wait(pending, return_when=FIRST_COMPLETED)
            for future in finished:
                task = pending.pop(future)
                error = future.exception()
                if error is None:
                    progress.step(task.key)
                    continue
                attempts[task.key] += 1
                if attempts[task.key] > retries:
                    failures[task.key] = str(error)
                    progress.step(f"{task.key} failed")
                    continue
                retry = pool.submit(run_task_process, task.to_json(), str(shards), timeout)
                pending[retry] = task
    return failures


def _run_dask(
    todo: Sequence[Task],
    shards: Path,
    scheduler: str,
    retries: int,
    timeout: float | None,
    progress: _Progress,
) -> dict[str, str]:
    try:
        from dask.distributed import Client, as_completed
    except ImportError as error:  # pragma: no cover - depends on the environment
        raise MissingExtra("dask[distributed]", "distributed") from error
    failures: dict[str, str] = {}
    try:
        client = Client(scheduler, timeout=f"{CONNECT_TIMEOUT:g}s")
    except (ValueError, TypeError) as error:  # an address Dask's connection code refuses
        raise ConfigError("scheduler", scheduler, f"{SCHEDULER_EXAMPLE} ({error})") from None
    with client:
        make_dir(shards)
        futures = {
            client.submit(
                run_task_process,
                t.to_json(),
                str(shards),
                timeout,
                key=f"openup-{t.key}",
                pure=False,
                retries=retries,
            ): t
            for t in todo
        }
        for future in as_completed(futures):
            task = futures[future]
            if future.status == "finished":
                progress.step(task.key)
            else:
                failures[task.key] = str(future.exception())
                progress.step(f"{task.key} failed")
    return failures


def load_records(tasks: Iterable[Task], shards: str | Path) -> list[dict[str, Any]]:
    """The records of the tasks that have a shard, in task order (one per key).

    Args:
        tasks: The sweep.
        shards: Directory of the shard files.

    Returns:
        The finished tasks' records (their result dictionaries).
    """
    records = []
    for task in tasks:
        path = shard_path(Path(shards), task.key)
        if path.exists():
            records.append(json.loads(path.read_text()))
    return records


def selfcheck_task(
    seed: int, marker: str | None = None, kill: str = "self", fail: bool = False
) -> dict[str, Any]:
    """A cheap task that shows what the executor guarantees (used by its tests).

    Returns draws from OMPL's process-wide generator (seeded by the executor) and the
    process id. With ``marker``, the first run creates that file and is killed (SIGKILL):
    its own process (``kill="self"``, a crashed run), or with ``kill="worker"`` the
    process that launched it, then its own (a Dask worker dying mid-task). ``fail``
    raises instead.

    Args:
        seed: The task's seed.
        marker: A file whose absence makes the run kill itself after creating it.
        kill: ``"self"`` or ``"worker"``: which process the first run kills.
        fail: Raise instead of returning.

    Returns:
        ``{"seed": seed, "draws": [three uniform draws], "pid": process id}``.
    """
    import signal

    from ompl import util as ompl_util

    if fail:
        raise RuntimeError("selfcheck_task asked to fail")
    if kill not in ("self", "worker"):
        raise ConfigError("kill", kill, "'self' or 'worker'")
    if marker is not None and not Path(marker).exists():
        Path(marker).write_text(str(os.getppid() if kill == "worker" else os.getpid()))
        if kill == "worker":
            os.kill(os.getppid(), signal.SIGKILL)
        os.kill(os.getpid(), signal.SIGKILL)
    rng = ompl_util.RNG()
    return {
        "seed": seed,
        "draws": [rng.uniformReal(0.0, 1.0) for _ in range(3)],
        "pid": os.getpid(),
    }


def _main(argv: Sequence[str]) -> int:
    """Task process entry: the task JSON on stdin, the shard directory as argument."""
    task = Task(**json.loads(sys.stdin.read()))
    _execute(task, Path(argv[0]))
    return 0


if __name__ == "__main__":
    status = _main(sys.argv[1:])
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(status)
