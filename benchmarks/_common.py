"""Helpers shared by the benchmark scripts: machine description, statistics, output."""

from __future__ import annotations

import json
import math
import os
import platform
import statistics
import subprocess
from collections.abc import Sequence
from importlib import metadata
from pathlib import Path
from typing import Any

from openup_ompl._io import json_safe


def cpu_model() -> str:
    """CPU model name from /proc/cpuinfo ("unknown" elsewhere)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def git_state() -> str | None:
    """Commit of the repository the benchmarks live in, "+dirty" with local changes."""
    root = Path(__file__).resolve().parent.parent
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], cwd=root, capture_output=True, text=True
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=root,
            capture_output=True,
            text=True,
        ).stdout.strip()
    except OSError:
        return None
    return f"{commit}+dirty" if commit and dirty else commit or None


def machine_info() -> dict[str, Any]:
    """What the numbers were measured on."""
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = os.cpu_count() or 1
    versions = {}
    for package in ("ompl", "pin", "coal", "numpy", "openup-ompl"):
        try:
            versions[package] = metadata.version(package)
        except metadata.PackageNotFoundError:
            versions[package] = None
    return {
        "nproc": usable,
        "cpu_model": cpu_model(),
        "python": platform.python_version(),
        "platform": platform.platform(),
        "loadavg": list(os.getloadavg()) if hasattr(os, "getloadavg") else None,
        "versions": versions,
        "git": git_state(),
        "native_built": native_built(),
    }


def native_built() -> bool | None:
    """Whether the compiled coupled check is built for the versions in use (then the
    package's checkers use it unless told ``native="off"``); ``None`` if unknown."""
    try:
        from openup_ompl import native
    except ImportError:
        return None
    return native.status()[0]


def machine_line(info: dict[str, Any]) -> str:
    versions = ", ".join(f"{k} {v}" for k, v in info["versions"].items() if v)
    load = info.get("loadavg")
    load_text = f", load average {load[0]:.2f} at start" if load else ""
    git = f", repository at {info['git']}" if info.get("git") else ""
    built = info.get("native_built")
    native = "" if built is None else f", compiled check {'built' if built else 'not built'}"
    return (
        f"Machine: {info['nproc']} cores, {info['cpu_model']}, Python {info['python']} "
        f"({versions}){load_text}{git}{native}"
    )


def median(values: Sequence[float]) -> float:
    return float(statistics.median(values)) if values else math.nan


def percentile(values: Sequence[float], q: float) -> float:
    """Linear-interpolation percentile (numpy's default), ``q`` in [0, 100]."""
    if not values:
        return math.nan
    data = sorted(values)
    pos = (len(data) - 1) * q / 100.0
    low = math.floor(pos)
    high = min(low + 1, len(data) - 1)
    return data[low] + (data[high] - data[low]) * (pos - low)


def markdown_table(header: Sequence[str], rows: Sequence[Sequence[object]], left: int = 1) -> str:
    """A Markdown table; the first ``left`` columns left-aligned, the others right-aligned."""
    cells = [[str(c) for c in header]] + [[str(c) for c in row] for row in rows]
    widths = [max(len(row[i]) for row in cells) for i in range(len(header))]

    def line(row: Sequence[str]) -> str:
        parts = [
            cell.ljust(width) if i < left else cell.rjust(width)
            for i, (cell, width) in enumerate(zip(row, widths, strict=True))
        ]
        return "| " + " | ".join(parts) + " |"

    dashes = [
        ":" + "-" * (w + 1) if i < left else "-" * (w + 1) + ":" for i, w in enumerate(widths)
    ]
    rule = "|" + "|".join(dashes) + "|"
    return "\n".join([line(cells[0]), rule, *(line(row) for row in cells[1:])])


def write_json(path: str | None, payload: dict[str, Any]) -> None:
    """Write ``payload`` to ``path`` (nothing if ``path`` is None); NaN becomes null."""
    if not path:
        return

    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text(json.dumps(json_safe(payload), indent=1, allow_nan=False) + "\n")


def recheck_plans(plans: Sequence[Any]) -> tuple[int, int]:
    """Re-check plans (``openup_ompl.Plan``) with the independent ``tests/recheck.py``:
    each is saved, reloaded from its file and checked for start, grasp pose, hand law and
    collision. Returns ``(checked, passed)``."""
    import sys
    import tempfile

    tests = str(Path(__file__).resolve().parent.parent / "tests")
    if tests not in sys.path:
        sys.path.insert(0, tests)
    from recheck import recheck_plan

    passed = 0
    with tempfile.TemporaryDirectory() as directory:
        for index, plan in enumerate(plans):
            data = json.loads(plan.save(Path(directory) / f"plan{index}.json").read_text())
            result = recheck_plan(data)
            passed += (
                result.start_error < 1e-9
                and not result.colliding
                and result.position_error <= 1e-3
                and result.rotation_error <= 1e-2
                and result.hand_error < 1e-9
            )
    return len(plans), int(passed)
