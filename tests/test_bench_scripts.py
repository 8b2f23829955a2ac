"""The benchmark scripts the README quotes run to their end on tiny sizes and write what
they say they write (a script that no longer runs would otherwise go unnoticed until the
next measurement)."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _run(script: str, *args: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / script), *args],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )


def test_bench_validity_runs_both_parts(tmp_path: Path) -> None:
    """Per-state table and motion table, every motion verdict agreeing between the
    all-cores and the one-thread world (the script asserts it)."""
    out = tmp_path / "validity.json"
    done = _run(
        "bench_validity.py",
        *("--states", "300", "--rounds", "1", "--motions", "12", "--motion-rounds", "1"),
        *("--json", str(out)),
    )
    assert done.returncode == 0, done.stderr[-2000:]
    result = json.loads(out.read_text())
    assert result["motions"], "no motion rows"
    for entry in result["motions"]:
        both = entry["all"]
        assert both["motions"] == entry["motions"] == 12
        # The same motions cut the same way whichever world checks them.
        assert both["batch"]["states"] == both["serial"]["states"] >= entry["motions"]


def test_bench_speed_compares_each_fixed_preshape(tmp_path: Path) -> None:
    """One seed of the Panda suite: the law's price against each ``--fixed`` preshape, every
    run solved, and the plans it re-checks pass."""
    out = tmp_path / "speed.json"
    done = _run(
        "bench_speed.py",
        *("--robots", "panda", "--planners", "ikbirrt", "--seeds", "1", "--cli-runs", "0"),
        *("--fixed", "w", "b", "--recheck-every", "4", "--json", str(out)),
    )
    assert done.returncode == 0, done.stderr[-2000:]
    result = json.loads(out.read_text())
    assert {p["against"] for p in result["prices"]} == {"fixed w", "fixed b"}
    assert {c["hand"] for c in result["cells"]} == {"law", "fixed w", "fixed b"}
    assert all(run["solved"] for run in result["runs"])
    assert result["recheck"]["checked"] >= 1
    assert result["recheck"]["passed"] == result["recheck"]["checked"]
    assert re.search(r"\|\s*panda\s*\|\s*ikbirrt\s*\|\s*`b`\s*\|", done.stdout)
