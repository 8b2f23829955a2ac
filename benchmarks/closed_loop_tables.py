"""Join closed-loop runs and write their tables: `openup-ompl closed-loop` runs one view
after another, so a long run is split into seed ranges run side by side (``--seed 1
--trials 15`` and ``--seed 16 --trials 15``), and their ``closed_loop_trials.json`` are
joined here into one table with Wilson 95 % intervals (``closed_loop.csv``), the paired
comparisons with the exact McNemar test (``closed_loop_pairs.csv``) and the figure.

Run::

    python benchmarks/closed_loop_tables.py RUN_A RUN_B --out DIR --title "closed loop, panda"

(``RUN_A`` and ``RUN_B``: the ``--out`` directories of the runs, or their trials files.)
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from openup_ompl.perception.cli import write_closed_loop


def load_records(paths: list[Path]) -> list[dict[str, Any]]:
    """Every run's records, refusing a view (noise, distance, seed, policy) two runs share."""
    records: list[dict[str, Any]] = []
    seen: dict[tuple[Any, ...], Path] = {}
    for path in paths:
        trials = path / "closed_loop_trials.json" if path.is_dir() else path
        for record in json.loads(trials.read_text()):
            key = (record["noise"], record["distance"], record["seed"], record["policy"])
            if key in seen:
                sys.exit(f"closed_loop_tables: {key} is in {seen[key]} and in {trials}")
            seen[key] = trials
            records.append(record)
    return records


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", type=Path, nargs="+", help="run directories or trials files")
    parser.add_argument("--out", type=Path, required=True, help="output directory")
    parser.add_argument("--title", default="", help="the figure's title")
    args = parser.parse_args()
    write_closed_loop(load_records(args.runs), args.out, args.title)


if __name__ == "__main__":
    main()
