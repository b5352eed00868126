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
import contextlib
import importlib
import os
import re
import signal
import sys
import textwrap
import threading
import warnings
from collections.abc import Iterator, Sequence
from types import FrameType
from typing import NoReturn, TextIO

from humotion_gym.cli._common import (
    CommandError,
    UsageError,
    check_mocap_paths,
    hold_output_folders,
    make_output_folders,
)
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

#: ``humotion-gym --help`` lists the commands in these groups, in this order;
#: a command in none of them is listed last, under "other commands".
COMMAND_GROUPS: dict[str, tuple[str, ...]] = {
    "everyday commands": (
        "tasks", "agents", "track", "leaderboard", "report", "train", "data", "download",
        "cache", "render",
    ),
    "research commands (the papers' experiments)": (
        "select", "still", "depth", "discrimination", "tree", "pca", "slds", "synth", "sweep",
        "learning-curve",
    ),
}  # fmt: skip

#: Extras that provide optional modules, for the hint when one is missing.
_EXTRAS = {"matplotlib": "plots", "stable_baselines3": "rl", "torch": "rl"}


#: Terminal colour codes, which some libraries put in their warnings' text.
_ANSI = re.compile(r"\x1b\[[0-9;]*m")


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line on stderr (exit 2).

    argparse prints the usage block before the error; the README promises one
    line, so the usage is replaced by a pointer to ``--help``.
    """

    def error(self, message: str) -> NoReturn:  # noqa: D102 (argparse's)
        print(f"{self.prog}: error: {message} (see {self.prog} --help)", file=sys.stderr)
        sys.exit(2)


#: Set to 1 to see the traceback of an error the command line reports in one line.
TRACEBACK_ENV = "HUMOTION_TRACEBACK"


def _runtime_errors() -> tuple[type[BaseException], ...]:
    """Exceptions reported as one line with exit code 1 (the user can act on them).

    ``ValueError`` is how the packages refuse what they are given, naming it;
    ``EOFError`` is a truncated compressed file.
    """
    from humotion_gym.errors import MocapFormatError, RigError
    from humotion_gym.mocap.download import DownloadError
    from humotion_gym.mocap.persons import SplitError

    return (
        CommandError, OSError, MocapFormatError, RigError, DownloadError, SplitError,
        ValueError, EOFError,
    )  # fmt: skip


def _grouped_listing(sub: argparse._SubParsersAction) -> str:
    """The commands with their one-line help, under :data:`COMMAND_GROUPS`' headings."""
    helps = {a.dest: a.help or "" for a in sub._choices_actions}
    width = max(map(len, helps), default=0) + 2
    listed: set[str] = set()
    blocks = []
    groups = dict(COMMAND_GROUPS)
    groups["other commands"] = tuple(n for n in helps if not any(n in g for g in groups.values()))
    for title, names in groups.items():
        rows = [f"  {n:{width}s}{helps[n]}" for n in names if n in helps and n not in listed]
        listed.update(names)
        if rows:
            blocks.append(f"{title}:\n" + "\n".join(rows))
    return "\n\n".join(blocks)


def build_parser(modules: Sequence[str] = COMMAND_MODULES) -> argparse.ArgumentParser:
    """The argument parser of ``humotion-gym`` over the given command modules.

    Args:
        modules: Dotted names of modules with a ``register(subparsers)`` function,
            in ``--help`` order (default: the benchmark's own, :data:`COMMAND_MODULES`).
    """
    from humotion_gym import __version__

    parser = OneLineParser(
        prog="humotion-gym",
        description=textwrap.fill(
            "Gymnasium environments for monocular 3D human pose tracking, and the trackers "
            "that score on them. Exit codes: 0 success, 1 runtime error, 2 usage error (each "
            "error is one line on stderr), 130 interrupted (Ctrl-C), 143 terminated "
            "(SIGTERM). Run humotion-gym COMMAND --help for a command's flags and an example.",
            78,
        ),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(
        dest="command", required=True, metavar="COMMAND", help=argparse.SUPPRESS
    )
    # set after add_subparsers, which builds the commands' prog from the usage
    parser.usage = "humotion-gym [-h] [--version] COMMAND ..."
    for name in modules:
        importlib.import_module(name).register(sub)
    parser.epilog = _grouped_listing(sub)
    return parser


def _group_named(
    parser: argparse.ArgumentParser, argv: list[str]
) -> argparse.ArgumentParser | None:
    """The parser of a command group that ``argv`` names and nothing more, else None.

    ``[]`` is the top's; ``["data"]`` is ``data``'s, whose subcommands its help
    lists; ``["track"]`` (a command, not a group) and anything with flags are None.
    """
    for name in argv:
        subs = _subcommands(parser)
        if subs is None or name not in subs.choices:
            return None
        parser = subs.choices[name]
    return parser if _subcommands(parser) is not None else None


def _command_parser(
    parser: argparse.ArgumentParser, args: argparse.Namespace
) -> argparse.ArgumentParser:
    """The parser of the (sub)command ``args`` were parsed for: ``data info``'s, not the top's."""
    while (subs := _subcommands(parser)) is not None and getattr(args, subs.dest, None):
        parser = subs.choices[getattr(args, subs.dest)]
    return parser


def _subcommands(parser: argparse.ArgumentParser) -> argparse._SubParsersAction | None:
    """A (group) parser's subcommands, None for a command without any."""
    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return subs[0] if subs else None


def _error(parser: argparse.ArgumentParser, args: argparse.Namespace, message: str) -> None:
    prog = " ".join(
        [parser.prog]
        + [
            str(v)
            for k, v in vars(args).items()
            if k == "command" or (k.endswith("_command") and v) or (k == "source" and v)
        ]
    )
    print(f"{prog}: error: {' '.join(message.split())}", file=sys.stderr)


def _check_inputs(args: argparse.Namespace) -> None:
    """Refuse mocap that a command cannot use before it starts any work.

    ``--data-dir`` (else ``$HUMOTION_MOCAP``) is loaded here (into the cache
    the command then reads); the ``PATH``, ``--train`` and ``--test``
    arguments are checked for motion capture.
    """
    from humotion_gym.mocap.library import MOCAP_ENV, configured_data_dirs, load_library

    dirs, flag = getattr(args, "data_dir", None), "--data-dir"
    if not dirs and hasattr(args, "data_dir"):
        dirs, flag = configured_data_dirs(None), f"${MOCAP_ENV}"
    if dirs:
        check_mocap_paths(dirs, flag)
        load_library(dirs, fps=getattr(args, "fps", 30.0), progress=True)
    for attr, flag in (("paths", "PATH"), ("train", "--train"), ("test_paths", "--test")):
        value = getattr(args, attr, None)
        if value:
            check_mocap_paths(value, flag)


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where the command is, so that it ends as Ctrl-C does (exit code 143).

    A ``KeyboardInterrupt``: every ``finally`` runs, and the command ends in one line.
    """


def interrupted(exc: KeyboardInterrupt, who: str, more: str = "") -> int:
    """Say on stderr that ``who`` was interrupted (``who: interrupted`` then ``more``).

    Returns:
        The exit code: 143 for SIGTERM (:class:`Terminated`), 130 for Ctrl-C.
    """
    word, code = ("terminated", 143) if isinstance(exc, Terminated) else ("interrupted", 130)
    print(f"{who}: {word}{more}", file=sys.stderr)
    return code


def _raise_terminated(signum: int, frame: FrameType | None) -> NoReturn:
    raise Terminated


def _default_in_child() -> None:
    # A process forked while a command runs (a fit's workers) dies of SIGTERM as
    # before: raising in a pool's idle worker would print its traceback.
    if signal.getsignal(signal.SIGTERM) is _raise_terminated:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_default_in_child)


@contextlib.contextmanager
def terminated_as_interrupt() -> Iterator[None]:
    """While the block runs, SIGTERM raises :class:`Terminated` (main thread only).

    The console scripts run the command line under it; :func:`main` called
    from a program leaves SIGTERM to the program.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def main(argv: Sequence[str] | None = None, modules: Sequence[str] = COMMAND_MODULES) -> int:
    """Run one command line over the given command modules; returns the exit code.

    The bare command, or a bare command group (``data``), prints its help and
    exits 0. A usage error ends in one line and exit code 2, an error the
    user can act on (:func:`_runtime_errors`) in one line and 1 (with
    ``HUMOTION_TRACEBACK=1``, its traceback), Ctrl-C in one line and 130
    (SIGTERM, under :func:`terminated_as_interrupt`, 143); any other
    exception is a bug and keeps its traceback.

    Args:
        argv: The arguments (default: ``sys.argv[1:]``).
        modules: The command modules (see :func:`build_parser`).
    """
    try:
        parser = build_parser(modules)
        argv = list(sys.argv[1:] if argv is None else argv)
        group = _group_named(parser, argv)
        if group is not None:  # the bare command, or a bare group (data, slds): its help
            group.print_help()
            return 0
        try:
            args, extra = parser.parse_known_args(argv)
            if extra:  # said by the command's own parser, which names the command
                _command_parser(parser, args).error(f"unrecognized arguments: {' '.join(extra)}")
        except SystemExit as exc:  # --help, --version (0) or a usage error (2)
            return exc.code if isinstance(exc.code, int) else 2
    except KeyboardInterrupt as exc:  # before the command started: nothing written
        return interrupted(exc, "humotion-gym")
    limit_blas_threads()  # see humotion_gym.threads for why and for Python users
    with warnings.catch_warnings():  # restores the caller's warning display on return
        warnings.showwarning = one_line_warning
        return _run(parser, args)


def one_line_warning(
    message: Warning | str,
    category: type[Warning],
    filename: str,
    lineno: int,
    file: TextIO | None = None,
    line: str | None = None,
) -> None:
    """Show a warning as one line on stderr, like the command's errors (colour codes dropped)."""
    text = " ".join(_ANSI.sub("", str(message)).split())
    print(f"humotion-gym: warning: {text} ({category.__name__})", file=file or sys.stderr)


def _run(parser: argparse.ArgumentParser, args: argparse.Namespace) -> int:
    """Run the parsed command; its errors as one line and an exit code (see :func:`main`)."""
    try:
        _check_inputs(args)
        make_output_folders(args)
        with hold_output_folders(args):
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
    except KeyboardInterrupt as exc:  # what was written stays (commands write as they go)
        return interrupted(exc, f"{parser.prog} {args.command}")
    except _runtime_errors() as exc:
        if os.environ.get(TRACEBACK_ENV) == "1":
            raise
        _error(parser, args, str(exc))
        return 1
