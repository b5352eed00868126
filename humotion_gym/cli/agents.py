"""``humotion-gym agents``: the agents ``track``, ``leaderboard`` and ``select`` accept.

::

    humotion-gym agents [--json]
"""

from __future__ import annotations

import argparse
from typing import Any

from humotion_gym.cli._common import add_json, print_json


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``agents``."""
    cmd = subparsers.add_parser("agents", help="list the agents (references, particle filters)")
    add_json(cmd, "one JSON object per agent instead of a table")
    cmd.set_defaults(func=_cmd_agents)


def _cmd_agents(args: argparse.Namespace) -> int:
    from baselines.agents import AGENTS, REFERENCES, agent_names
    from baselines.learned import LEARNED

    rows: list[dict[str, Any]] = []
    for name in agent_names():
        if name in REFERENCES:
            rows.append({"agent": name, "kind": "reference", "prior": None, "tasks": None,
                         "description": REFERENCES[name][1]})  # fmt: skip
        elif name in AGENTS:
            spec = AGENTS[name]
            rows.append({
                "agent": name, "kind": "particle filter", "prior": spec.prior,
                "tasks": list(spec.tasks) if spec.tasks is not None else None,
                "description": spec.description,
            })  # fmt: skip
        else:
            rows.append({"agent": name, "kind": "learned", "prior": None, "tasks": None,
                         "description": LEARNED.get(name, "")})  # fmt: skip
    if args.json:
        for r in rows:
            print_json(r)
        return 0
    width = max(len(r["agent"]) for r in rows)
    for r in rows:
        tasks = f" [tasks: {', '.join(r['tasks'])}]" if r["tasks"] else ""
        print(f"{r['agent']:{width}s}  {r['kind']:15s}  {r['description']}{tasks}")
    return 0
