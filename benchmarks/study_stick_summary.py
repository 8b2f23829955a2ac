"""Counts over replayed study trials: how the hand first touched the object and what
followed, per ``u`` (the measurements ``study_trial_figure.py --json`` writes).

Run (every trial of the LWA3-SDH's thin stick, perceived, seed 2: about ten minutes)::

    python benchmarks/study_trial_figure.py --trial $(seq 0 199) --json stick.json
    python benchmarks/study_stick_summary.py stick.json
"""

from __future__ import annotations

import argparse
import json
import statistics
from pathlib import Path
from typing import Any

#: Bins [mm] of the fingers' closest pass by the believed stick before the first touch.
BINS = ((-float("inf"), 5.0), (5.0, 10.0), (10.0, 20.0), (20.0, float("inf")))


def summary(rows: list[dict[str, Any]]) -> list[str]:
    """Lines of counts for one ``u``'s rows."""
    reach = [r for r in rows if r["first_touch"] and r["first_touch"]["phase"] == "reach"]
    failed = [r for r in rows if r["cause"] is not None]
    top = [r for r in reach if r["touch_height_mm"] >= r["stick_length_mm"] - 1.0]
    tipped = [r for r in reach if r["after_reach"]["tilt_deg"] > 45.0]
    lines = [
        f"{len(rows)} trials, {len(failed)} failed; {len(reach)} touched during the reach,"
        f" {sum(r['cause'] is not None for r in reach)} of them failed",
        f"  at the top end {len(top)} ({sum(r['cause'] is not None for r in top)} failed);"
        f" tipped over 45 deg by the end of the reach {len(tipped)}"
        f" ({sum(r['cause'] is not None for r in tipped)} failed)",
    ]
    if reach:
        apertures = [r["aperture_at_touch_mm"] for r in reach]
        ds = [r["first_touch"]["d"] for r in reach]
        lines.append(
            f"  at those touches: aperture {min(apertures):.0f}-{max(apertures):.0f} mm,"
            f" d {min(ds):.2f}-{max(ds):.2f}"
        )
    passes = [r for r in rows if "believed_clearance_mm" in r]
    for low, high in BINS:
        inside = [r for r in passes if low <= r["believed_clearance_mm"] < high]
        failures = sum(r["cause"] is not None for r in inside)
        span = (
            f"under {high:g}"
            if low < 0
            else f"{low:g} or more"
            if high > 1e9
            else f"{low:g}-{high:g}"
        )
        lines.append(f"  closest pass by the believed stick {span} mm: {len(inside)} trials,"
                     f" {failures} failed")  # fmt: skip
    for name, group in (("held", [r for r in passes if r["cause"] is None]),
                        ("failed", [r for r in passes if r["cause"] is not None])):  # fmt: skip
        if group:
            median = statistics.median(r["believed_clearance_mm"] for r in group)
            lines.append(f"  median closest pass, {name}: {median:.1f} mm")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("measurements", type=Path, help="study_trial_figure.py --json output")
    args = parser.parse_args()
    rows = json.loads(args.measurements.read_text())
    for u in sorted({r["u"] for r in rows}):
        print(f"u = {u:g}:")
        for line in summary([r for r in rows if r["u"] == u]):
            print(line)


if __name__ == "__main__":
    main()
