"""``humotion-gym agents``: the agents ``track``, ``leaderboard`` and ``select`` accept.

::

    humotion-gym agents [--json]
    humotion-gym agents --task BodyTrack-v2   # with each filter's settings on the task
"""

from __future__ import annotations

import argparse
import math
from typing import Any

from baselines.cli._args import add_imports, tracked_task
from humotion_gym.cli._common import add_command, add_json, print_json


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``agents``."""
    cmd = add_command(
        subparsers,
        "agents",
        "list the agents (references, particle filters, learned policies)",
        "humotion-gym agents --task BodyTrack-v2",
        details="With --task, each particle filter's settings on that "
        "task: those its registration sets for the prior's fit (the rest are the prior's "
        "defaults) and the filter's own (layers, survival rate alpha, diffusion, exponent "
        "cap beta_max; those of the annealed filter).",
    )
    cmd.add_argument(
        "--task", type=tracked_task, default=None,
        help="show each particle filter's settings on this task (default: none shown)",
    )  # fmt: skip
    add_imports(cmd)
    add_json(cmd, "one JSON object per agent instead of a table")
    cmd.set_defaults(func=_cmd_agents)


def _plain_settings(settings: dict[str, Any]) -> dict[str, Any]:
    """Settings as plain JSON: an infinite value (no cap) becomes None."""
    return {k: None if isinstance(v, float) and math.isinf(v) else v for k, v in settings.items()}


def _filter_settings(spec: Any, task: str) -> dict[str, Any]:
    """The filter's settings that apply: the plain filter has layers alone."""
    settings = spec.filter_settings_for(task)
    if spec.partitioned:
        return {"partitioned": True, "diffusion": settings["diffusion"]}
    if settings["layers"] == 1:
        return {"layers": 1}
    return settings


def _settings_text(settings: dict[str, Any]) -> str:
    return ", ".join(f"{k}={'none' if v is None else v}" for k, v in settings.items()) or "-"


def _cmd_agents(args: argparse.Namespace) -> int:
    from baselines.agents import AGENTS, LEARNED, REFERENCES, agent_names
    from humotion_gym.envs.tasks import get_task

    # a multi-view variant is its task with more cameras: the task's settings
    task = None if args.task is None else get_task(args.task).name
    rows: list[dict[str, Any]] = []
    for name in agent_names():
        if name in REFERENCES:
            rows.append({"agent": name, "kind": "reference", "prior": None, "tasks": None,
                         "description": REFERENCES[name][1]})  # fmt: skip
        elif name in AGENTS:
            spec = AGENTS[name]
            row: dict[str, Any] = {
                "agent": name, "kind": "particle filter", "prior": spec.prior,
                "tasks": list(spec.tasks) if spec.tasks is not None else None,
                "description": spec.description,
            }  # fmt: skip
            if task is not None and (spec.tasks is None or task in spec.tasks):
                row["settings"] = {
                    "task": task,
                    "fit": _plain_settings(spec.settings_for(task)),
                    "filter": _plain_settings(_filter_settings(spec, task)),
                }
            rows.append(row)
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
        if "settings" in r:
            pad = " " * (width + 2 + 15 + 2)
            print(f"{pad}on {args.task}: fit {_settings_text(r['settings']['fit'])}")
            print(f"{pad}{' ' * len('on ' + args.task + ': ')}filter "
                  f"{_settings_text(r['settings']['filter'])}")  # fmt: skip
    return 0
