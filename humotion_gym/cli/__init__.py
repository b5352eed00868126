"""The ``humotion-gym`` command line.

Every command group is one module of this package with a
``register(subparsers)`` function that adds its sub-parser(s) and sets
``func`` (a function of the parsed ``argparse.Namespace`` returning the exit
code). :data:`COMMAND_MODULES` lists those modules in the order ``--help``
shows them; **a new command is one new module here plus one line in that
list**. Command modules import heavy dependencies inside their command
functions so that ``humotion-gym --help`` stays fast.

Shared argument types (``positive_int``, ``task_name``...), the common flags
(``--data-dir``, ``--json``, ``--seed``) and the two errors a command raises
(:class:`~humotion_gym.cli._common.UsageError`, exit 2;
:class:`~humotion_gym.cli._common.CommandError`, exit 1) are in
:mod:`humotion_gym.cli._common`. Exit codes: 0 success, 1 a runtime error the
user can act on (one line on stderr), 2 a usage error; any other exception is
a bug and keeps its traceback.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Sequence

from humotion_gym.cli._common import CommandError, UsageError
from humotion_gym.threads import limit_blas_threads

#: The command modules (``humotion_gym.cli.<name>``), in ``--help`` order.
COMMAND_MODULES: tuple[str, ...] = (
    "tasks",  # tasks: the environments
    "agents",  # agents: the reference agents and particle filters
    "data",  # data table|info|persons|convert
    "download",  # download cmu
    "cache",  # cache info|clear
    "render",  # render
    "track",  # track
    "leaderboard",  # leaderboard
    "select",  # select
    "still",  # still (every agent where the person barely moves)
    "discrimination",  # discrimination
    "depth",  # depth (each agent's error along and across the line of sight)
    "synth",  # synth
    "tree",  # tree figures
    "pca",  # pca period|figures
    "slds",  # slds classify|select|splits|interpolate|figures
    "train",  # train, learning-curve (learned trackers)
    "report",  # report (tables, figures, videos, index.html of a saved leaderboard)
    "sweep",  # sweep (difficulty curves over environment settings)
)

#: Extras that provide optional modules, for the hint when one is missing.
_EXTRAS = {"matplotlib": "plots", "stable_baselines3": "rl", "torch": "rl"}


def _runtime_errors() -> tuple[type[BaseException], ...]:
    """Exceptions reported as one line with exit code 1 (the user can act on them)."""
    from humotion_gym.errors import MocapFormatError, RigError
    from humotion_gym.mocap.download import DownloadError
    from humotion_gym.mocap.persons import SplitError

    return (CommandError, OSError, MocapFormatError, RigError, DownloadError, SplitError)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``humotion-gym``, with every module of :data:`COMMAND_MODULES`."""
    parser = argparse.ArgumentParser(
        prog="humotion-gym",
        description="Gymnasium environments for monocular 3D human pose tracking. "
        "Exit codes: 0 success, 1 runtime error, 2 usage error.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in COMMAND_MODULES:
        importlib.import_module(f"{__name__}.{name}").register(sub)
    return parser


def _error(parser: argparse.ArgumentParser, args: argparse.Namespace, message: str) -> None:
    prog = " ".join(
        [parser.prog]
        + [
            str(v)
            for k, v in vars(args).items()
            if k == "command" or (k.endswith("_command") and v) or (k == "source" and v)
        ]
    )
    print(f"{prog}: error: {message}", file=sys.stderr)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``humotion-gym`` console script; returns the exit code."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help (0) or argparse's usage error (2)
        return exc.code if isinstance(exc.code, int) else 2
    limit_blas_threads()  # see humotion_gym.threads for why and for Python users
    try:
        return int(args.func(args) or 0)
    except BrokenPipeError:  # the output was piped into a reader that stopped (head)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
    except UsageError as exc:
        _error(parser, args, str(exc))
        return 2
    except ModuleNotFoundError as exc:
        extra = _EXTRAS.get(str(exc.name).split(".")[0])
        if extra is None:
            raise
        _error(parser, args, f"{exc}; install the {extra} extra: pip install -e '.[{extra}]'")
        return 1
    except _runtime_errors() as exc:
        _error(parser, args, str(exc))
        return 1
