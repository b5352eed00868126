"""The ``humotion-gym`` command line.

Every command group is one module of this package with a
``register(subparsers)`` function that adds its sub-parser(s) and sets
``func`` (a function of the parsed ``argparse.Namespace`` returning the exit
code). :data:`COMMAND_MODULES` lists the benchmark's modules in the order
``--help`` shows them, :data:`baselines.cli.COMMAND_MODULES` every module;
**a new command is one new module plus one line in one of those lists**.
Command modules import heavy dependencies inside their command functions so
that ``humotion-gym --help`` stays fast.

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

#: The benchmark's command modules, in ``--help`` order. The trackers' commands
#: (track, leaderboard, report, train and the papers' experiments) live in
#: :mod:`baselines.cli`, whose :func:`~baselines.cli.main` is the ``humotion-gym``
#: console script and adds them after these; this package never imports them.
COMMAND_MODULES: tuple[str, ...] = (
    "humotion_gym.cli.tasks",  # tasks: the environments
    "humotion_gym.cli.data",  # data table|info|persons|convert
    "humotion_gym.cli.download",  # download cmu
    "humotion_gym.cli.cache",  # cache info|clear
    "humotion_gym.cli.render",  # render
)

#: Extras that provide optional modules, for the hint when one is missing.
_EXTRAS = {"matplotlib": "plots", "stable_baselines3": "rl", "torch": "rl"}


def _runtime_errors() -> tuple[type[BaseException], ...]:
    """Exceptions reported as one line with exit code 1 (the user can act on them)."""
    from humotion_gym.errors import MocapFormatError, RigError
    from humotion_gym.mocap.download import DownloadError
    from humotion_gym.mocap.persons import SplitError

    return (CommandError, OSError, MocapFormatError, RigError, DownloadError, SplitError)


def build_parser(modules: Sequence[str] = COMMAND_MODULES) -> argparse.ArgumentParser:
    """The argument parser of ``humotion-gym`` over the given command modules.

    Args:
        modules: Dotted names of modules with a ``register(subparsers)`` function,
            in ``--help`` order (default: the benchmark's own, :data:`COMMAND_MODULES`).
    """
    parser = argparse.ArgumentParser(
        prog="humotion-gym",
        description="Gymnasium environments for monocular 3D human pose tracking. "
        "Exit codes: 0 success, 1 runtime error, 2 usage error.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in modules:
        importlib.import_module(name).register(sub)
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


def main(argv: Sequence[str] | None = None, modules: Sequence[str] = COMMAND_MODULES) -> int:
    """Run one command line over the given command modules; returns the exit code.

    Args:
        argv: The arguments (default: ``sys.argv[1:]``).
        modules: The command modules (see :func:`build_parser`).
    """
    parser = build_parser(modules)
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
