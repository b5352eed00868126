"""``humotion-gym tasks``: the tracking tasks (environment ids) and what each scores.

::

    humotion-gym tasks [--json]
"""

from __future__ import annotations

import argparse
from typing import Any

from humotion_gym.cli._common import add_command, add_json, print_json


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``tasks``."""
    cmd = add_command(
        subparsers, "tasks", "list the tasks (environment ids) and what each scores",
        "humotion-gym tasks --json",
    )  # fmt: skip
    add_json(cmd, "one JSON object per task instead of a table")
    cmd.set_defaults(func=_cmd_tasks)


def _cmd_tasks(args: argparse.Namespace) -> int:
    from humotion_gym.envs import (
        CURRENT_TASKS,
        DEPRECATED_TASKS,
        NAMESPACE,
        VIEW_VARIANTS,
        get_task,
    )

    # the current tasks, their multi-view variants, then the deprecated ones
    names = [t.name for t in CURRENT_TASKS] + list(VIEW_VARIANTS)
    deprecated = {t.name for t in DEPRECATED_TASKS}
    names += [t.name for t in DEPRECATED_TASKS]
    rows: list[dict[str, Any]] = []
    for name in names:
        t = get_task(name)
        views = f", {t.views} views" if t.views > 1 else ""
        # version 1 observes the frame alone: the trackers do not run it (docs/v1.md)
        old = "; deprecated: its frame alone, not tracked" if name in deprecated else ""
        rows.append(
            {
                "task": name,
                "id": f"{NAMESPACE}/{name}",
                "episode_frames": t.episode_frames,
                "free_params": len(t.free),
                "labels": list(t.labels) if t.labels is not None else None,
                "description": t.description + views + old,
                "views": t.views,
                "deprecated": name in deprecated,
            }
        )
    if args.json:
        for r in rows:
            print_json(r)
        return 0
    print(f"{'task':18s} {'frames':>6s} {'free':>4s} {'clips':12s} description")
    for r in rows:
        labels = ",".join(r["labels"]) if r["labels"] else "every clip"
        print(
            f"{r['task']:18s} {r['episode_frames']:6d} {r['free_params']:4d} {labels:12s} "
            f"{r['description']}"
        )
    print(f"gymnasium.make('{NAMESPACE}/<task>'); frames: scored frames per episode")
    return 0
