"""The ``humotion-gym`` command line: the benchmark's commands, then the trackers'.

The benchmark's own commands (tasks, data, download, cache, render) live in
:mod:`humotion_gym.cli`, which never imports this package; this module adds the
commands that run trackers (track, leaderboard, report, train) and the papers'
experiments, and is the ``humotion-gym`` console script's entry point. Each
command module has a ``register(subparsers)`` function, as described in
:mod:`humotion_gym.cli`.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import warnings
from collections.abc import Sequence

from humotion_gym import cli as benchmark_cli
from humotion_gym.cli import TRACEBACK_ENV, interrupted, one_line_warning

#: Every command module of ``humotion-gym``, in ``--help`` order.
COMMAND_MODULES: tuple[str, ...] = (
    "humotion_gym.cli.tasks",  # tasks: the environments
    "baselines.cli.agents",  # agents: the reference agents and particle filters
    *benchmark_cli.COMMAND_MODULES[1:],  # data, download, cache, render
    "baselines.cli.track",  # track
    "baselines.cli.leaderboard",  # leaderboard
    "baselines.cli.select",  # select
    "baselines.cli.still",  # still (every agent where the person barely moves)
    "baselines.cli.discrimination",  # discrimination
    "baselines.cli.depth",  # depth (each agent's error along and across the line of sight)
    "baselines.cli.oracle",  # oracle (each agent's error with truth oracles in its likelihood)
    "baselines.cli.synth",  # synth
    "baselines.cli.tree",  # tree figures
    "baselines.cli.pca",  # pca period|figures
    "baselines.cli.slds",  # slds classify|select|splits|interpolate|figures
    "baselines.cli.train",  # train, learning-curve (learned trackers)
    "baselines.cli.detector",  # detector train (the learned 2D keypoint detector)
    "baselines.cli.report",  # report (tables, figures, videos of a saved leaderboard)
    "baselines.cli.compare",  # compare (a rerun against a recorded run, episode by episode)
    "baselines.cli.ratio",  # ratio (two cells at the interval of their ratio)
    "baselines.cli.sweep",  # sweep (difficulty curves over environment settings)
)


def build_parser() -> argparse.ArgumentParser:
    """The parser of ``humotion-gym`` with every command."""
    return benchmark_cli.build_parser(COMMAND_MODULES)


#: The commands that take ``--import MODULE`` (:func:`baselines.cli._args.add_imports`).
IMPORTING_COMMANDS: frozenset[str] = frozenset(
    {"agents", "track", "select", "leaderboard", "still", "sweep", "depth"}
)


def import_agent_modules(argv: Sequence[str]) -> int | None:
    """Import each ``--import MODULE`` of ``argv``; an exit code where one fails, else None.

    Done before the arguments are parsed, so that the agents a module
    registers are known to ``--agents``. The current folder is put on the
    import path (a console script's is not; the leaderboard's Ray workers take
    the driver's). A module that is not found is a usage error (2); one that
    fails while importing, a runtime error (1), its traceback with
    ``HUMOTION_TRACEBACK=1``.
    """
    if not argv or argv[0] not in IMPORTING_COMMANDS:
        return None  # the command has no --import: its parser says so
    # the flag as the command's parser reads it (abbreviations included)
    pre = argparse.ArgumentParser(add_help=False)
    pre.add_argument("--import", dest="imports", action="append", default=[])
    names = pre.parse_known_args(argv[1:])[0].imports
    if names and os.getcwd() not in sys.path:
        sys.path.append(os.getcwd())
    for name in names:
        try:
            with warnings.catch_warnings():  # as the command's own: one line each
                warnings.showwarning = one_line_warning
                importlib.import_module(name)
        except Exception as exc:
            missing = getattr(exc, "name", None) if isinstance(exc, ModuleNotFoundError) else None
            if missing and (name == missing or name.startswith(f"{missing}.")):
                print(
                    f"humotion-gym {argv[0]}: error: --import {name}: no module named {missing} (a "
                    "module on PYTHONPATH or in the current folder)",
                    file=sys.stderr,
                )
                return 2
            if os.environ.get(TRACEBACK_ENV) == "1":
                raise
            text = " ".join(str(exc).split())[:300]
            print(
                f"humotion-gym {argv[0]}: error: --import {name}: {type(exc).__name__}: {text}",
                file=sys.stderr,
            )
            return 1
    return None


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``humotion-gym`` console script; returns the exit code."""
    args = list(sys.argv[1:] if argv is None else argv)
    try:
        failed = import_agent_modules(args)
    except KeyboardInterrupt as exc:  # in a user's module, before the command ran
        return interrupted(exc, "humotion-gym")
    return failed if failed is not None else benchmark_cli.main(args, COMMAND_MODULES)
