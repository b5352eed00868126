"""Is each task's verdict the same under different sets of agent seeds?

Reads a leaderboard ``results.json`` run with ``agent_seeds`` a multiple of 5
(the same declared episodes for every seed), splits each cell's episodes into
sets of 5 consecutive agent seeds, summarises each set as the leaderboard
does (clip-level intervals) and prints every set's verdict line per task::

    python benchmarks/v2_seed_sets.py RESULTS.json [--set-size 5]

The verdict is :func:`baselines.leaderboard.tables.validity_lines` of the set's
rows: the best reference filter at the fewest particles, valid where the lower
bound of its ``x hold`` interval is at least 2.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from baselines.leaderboard.evaluation import summarize
from baselines.leaderboard.tables import validity_lines
from humotion_gym.cli._common import int_at_least
from humotion_gym.files import read_json


def seed_set_rows(rows: list[dict[str, Any]], seeds: list[int]) -> list[dict[str, Any]]:
    """The rows restricted to the agent seeds ``seeds`` (hold keeps its first seed)."""
    out = []
    for row in rows:
        if "episodes" not in row:
            continue
        if row["agent"] == "hold":  # deterministic: every seed gives the same episodes
            first = min(e["agent_seed"] for e in row["episodes"])
            kept = [e for e in row["episodes"] if e["agent_seed"] == first]
            kept = [{k: v for k, v in e.items() if k != "agent_seed"} for e in kept]
        else:
            kept = [e for e in row["episodes"] if e["agent_seed"] in seeds]
        by_clip = row["summary"].get("intervals") == "clip"
        out.append({**row, "episodes": kept, "summary": summarize(kept, by_clip=by_clip)})
    return out


def agent_seeds(rows: list[dict[str, Any]], source: Path, set_size: int) -> list[int]:
    """The run's agent seeds, or a ValueError naming ``source`` where they cannot be split."""
    episodes = [e for r in rows for e in r.get("episodes", [])]
    if not episodes or any("agent_seed" not in e for e in episodes):
        raise ValueError(
            f"{source}: its episodes carry no agent_seed (a run with agent_seeds=1); "
            f"this reads a run with agent_seeds a multiple of {set_size}"
        )
    seeds = sorted({int(e["agent_seed"]) for e in episodes})
    if len(seeds) < set_size:
        raise ValueError(f"{source}: {len(seeds)} agent seeds, fewer than --set-size {set_size}")
    return seeds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("results", type=Path)
    parser.add_argument("--set-size", type=int_at_least(1), default=5)
    args = parser.parse_args()
    try:
        rows = read_json(args.results)["rows"]
        seeds = agent_seeds(rows, args.results, args.set_size)
    except (OSError, ValueError, KeyError, TypeError) as exc:
        parser.exit(1, f"v2_seed_sets: {exc}\n")
    for k in range(0, len(seeds) - args.set_size + 1, args.set_size):
        chosen = seeds[k : k + args.set_size]
        print(f"agent seeds {chosen[0]}-{chosen[-1]}:")
        for line in validity_lines(seed_set_rows(rows, chosen)):
            if "best reference filter" in line:
                print("  " + line)


if __name__ == "__main__":
    main()
