"""``run_study``: the study on the project's executor, resumable, and its outputs."""

from __future__ import annotations

import json
import os
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from openup_ompl._io import make_dir
from openup_ompl.exceptions import ConfigError, MissingExtra
from openup_ompl.executor import load_records, run_tasks
from openup_ompl.study.report import (
    MAP_COLUMNS,
    PAIR_COLUMNS,
    map_rows,
    pair_rows,
    plot_study,
    write_rows,
)
from openup_ompl.study.run import StudyOptions, make_tasks

__all__ = ["StudyResult", "run_study"]


@dataclass(frozen=True)
class StudyResult:
    """What :func:`run_study` wrote and found.

    Attributes:
        map_csv: ``uncertainty_map.csv``.
        pairs_csv: ``uncertainty_pairs.csv``.
        figure: ``uncertainty_map.png``, or ``None`` without matplotlib.
        trials: ``trials.json`` (every trial's record).
        rows: The map's rows.
        pairs: The pairs' rows.
        records: One record per chunk of trials.
    """

    map_csv: Path
    pairs_csv: Path
    figure: Path | None
    trials: Path
    rows: list[dict[str, Any]]
    pairs: list[dict[str, Any]]
    records: list[dict[str, Any]]


def run_study(
    options: StudyOptions,
    out: str | Path,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    quiet: bool = False,
) -> StudyResult:
    """Run the study's missing chunks and write its outputs to ``out``.

    Args:
        options: The sweep.
        out: Output directory (its ``shards/`` keep finished chunks: a rerun resumes).
        workers: Local task processes at a time (default: the usable cores).
        scheduler: Dask scheduler address; ``None`` runs locally.
        quiet: No progress on stderr.

    Returns:
        The files written (CSVs, figure, ``trials.json``) and the rows, pairs and records.

    Raises:
        ConfigError: Bad options or ``out`` a file.
        SweepFailed: Some chunk failed on every attempt (the others' shards are kept).
    """
    if not isinstance(options, StudyOptions):
        raise ConfigError("options", options, "StudyOptions")
    if not isinstance(out, (str, os.PathLike)):
        raise ConfigError("out", out, "an output directory's path")
    out = make_dir(Path(out))
    tasks = make_tasks(options, (out / "meshes").resolve())
    run_tasks(tasks, out / "shards", workers=workers, scheduler=scheduler, quiet=quiet)
    records = load_records(tasks, out / "shards")
    rows = map_rows(records, options.policies)
    pairs = pair_rows(records, options.policies)
    trials = out / "trials.json"
    trials.write_text(json.dumps(records, indent=1) + "\n")
    map_csv = write_rows(rows, MAP_COLUMNS, out / "uncertainty_map.csv")
    pairs_csv = write_rows(pairs, PAIR_COLUMNS, out / "uncertainty_pairs.csv")
    figure: Path | None
    title = (
        f"held in physics, {options.trials} paired trials per cell, Wilson 95 % bands"
        f" (seed {options.seed})"
    )
    try:
        figure = plot_study(rows, options.errors, out / "uncertainty_map.png", title)
    except MissingExtra as error:
        print(f"no figure: {error}", file=sys.stderr)
        figure = None
    return StudyResult(map_csv, pairs_csv, figure, trials, rows, pairs, records)
