"""Where the study's ``capped`` policy loses: per trial, the ``u`` its swept-clearance cap
chose against whether it and ``u = 1`` held, from a study's shards (no trial is run).

Draws ``docs/results/study_adaptive.png``: for each family where the cap bit (the policy
chose ``u < 1`` in some trial), the trials' capped ``u`` with the four outcomes (both held,
only ``u = 1``, only the policy, neither) and the counts in the legend. ``--policy`` picks
another policy's ``u`` (``adaptive``, for instance, to see where it chose less than 1).

Run::

    python benchmarks/study_adaptive.py benchmarks/results/study_seed1/lwa3_sdh/shards \
        --policy adaptive --label capped --out docs/results/study_adaptive.png
"""

from __future__ import annotations

import argparse
import json
from collections import Counter
from pathlib import Path

from openup_ompl.viz._mpl import _pyplot, _save

OUTCOMES = {
    (True, True): ("both held", "tab:green"),
    (False, True): ("only u = 1 held", "tab:red"),
    (True, False): ("only {policy} held", "tab:blue"),
    (False, False): ("neither held", "tab:gray"),
}


def capped_trials(shards: Path, policy: str) -> dict[str, list[tuple[float, bool, bool]]]:
    """Per family, ``(the policy's u, it held, u = 1 held)`` of every trial in which the
    policy chose ``u < 1`` and both policies planned."""
    out: dict[str, list[tuple[float, bool, bool]]] = {}
    for path in sorted(shards.glob("*.json")):
        shard = json.loads(path.read_text())
        for trial in shard["trials"]:
            results = trial["results"]
            a, one = results.get(policy), results.get("1")
            if a is None or one is None or a.get("u") is None or a["u"] >= 1.0:
                continue
            if not (a.get("planned") and one.get("planned")):
                continue
            out.setdefault(shard["family"], []).append((a["u"], bool(a["held"]), bool(one["held"])))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("shards", type=Path, help="a study's shards directory")
    parser.add_argument("--out", type=Path, default=Path("study_adaptive.png"))
    parser.add_argument("--policy", default="capped", help="the policy whose u is shown")
    parser.add_argument("--label", default=None, help="its name in the figure (default: --policy)")
    args = parser.parse_args()
    name = args.label or args.policy
    trials = capped_trials(args.shards, args.policy)
    plt = _pyplot()
    fig, axes = plt.subplots(1, max(1, len(trials)), figsize=(4.2 * max(1, len(trials)), 3.4))
    axes = [axes] if len(trials) <= 1 else list(axes)
    for ax, (family, rows) in zip(axes, sorted(trials.items()), strict=False):
        counts = Counter((held_a, held_1) for _, held_a, held_1 in rows)
        for key, (label, colour) in OUTCOMES.items():
            us = [u for u, held_a, held_1 in rows if (held_a, held_1) == key]
            ys = [list(OUTCOMES).index(key)] * len(us)
            label = label.format(policy=name)
            ax.scatter(us, ys, s=14, color=colour, label=f"{label}: {counts[key]}")
        labels = [label.format(policy=name) for label, _ in OUTCOMES.values()]
        ax.set_yticks(range(4), labels, fontsize=7)
        ax.set_xlim(-0.05, 1.0)
        ax.set_xlabel(f"{name}'s u")
        ax.set_title(f"{family}: {len(rows)} trials with u < 1", fontsize=9)
        ax.legend(fontsize=6, loc="lower right")
        print(family, len(rows), dict(counts))
    fig.suptitle(f"where {name} chose u < 1: its u and the outcome against u = 1", fontsize=9)
    fig.tight_layout()
    _save(fig, args.out, dpi=120)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
