"""What the command modules share: errors, argument types, common flags.

Errors and exit codes (``humotion-gym`` exits with):

* 0 on success;
* 2 on a usage error: argparse's own (unknown flag, bad type), an argument
  type below that refuses a value, or :class:`UsageError` raised by a command,
  each naming the flag;
* 1 on a runtime error the user can act on: :class:`CommandError`, a file that
  cannot be read or written (``OSError``), a malformed mocap file, a failed
  download, a broken person split (see ``RUNTIME_ERRORS`` in
  :mod:`humotion_gym.cli`);
* anything else is a bug and keeps its traceback.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any


class UsageError(ValueError):
    """A command's arguments are wrong together (exit 2); the message names the flag."""


class CommandError(RuntimeError):
    """A command could not do its work for a reason the user can fix (exit 1)."""


def _number(kind: type, text: str) -> Any:
    try:
        return kind(text)
    except ValueError:
        what = "an integer" if kind is int else "a number"
        raise argparse.ArgumentTypeError(f"expected {what}, got {text}") from None


def int_at_least(low: int) -> Callable[[str], int]:
    """An argparse ``type`` accepting integers ``>= low`` (argparse names the flag)."""

    def parse(text: str) -> int:
        value = _number(int, text)
        if value < low:
            raise argparse.ArgumentTypeError(f"expected an integer >= {low}, got {text}")
        return value

    parse.__name__ = f"integer >= {low}"
    return parse


#: ``type=`` for counts that must be at least one (episodes, particles, frames...).
positive_int = int_at_least(1)
#: ``type=`` for seeds and other counts that may be zero.
nonnegative_int = int_at_least(0)


def positive_float(text: str) -> float:
    """An argparse ``type`` accepting finite numbers ``> 0``."""
    value = _number(float, text)
    if not (value > 0 and value < float("inf")):
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {text}")
    return value


def nonnegative_float(text: str) -> float:
    """An argparse ``type`` accepting finite numbers ``>= 0``."""
    value = _number(float, text)
    if not (value >= 0 and value < float("inf")):
        raise argparse.ArgumentTypeError(f"expected a finite number >= 0, got {text}")
    return value


def probability(text: str) -> float:
    """An argparse ``type`` accepting numbers in ``(0, 1)``."""
    value = _number(float, text)
    if not 0 < value < 1:
        raise argparse.ArgumentTypeError(f"expected a number between 0 and 1, got {text}")
    return value


def image_size(text: str) -> tuple[int, int]:
    """An argparse ``type`` for ``WIDTHxHEIGHT`` (e.g. ``256x256``), both positive."""
    parts = text.lower().split("x")
    try:
        width, height = (int(p) for p in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected WIDTHxHEIGHT, e.g. 256x256, got {text}"
        ) from None
    if width < 1 or height < 1:
        raise argparse.ArgumentTypeError(f"expected positive WIDTHxHEIGHT, got {text}")
    return width, height


def task_name(text: str) -> str:
    """An argparse ``type`` for a task id (``ArmTrack-v1``, also with ``humotion_gym/``)."""
    from humotion_gym.envs.tasks import TASKS

    name = text.split("/")[-1].split(":")[-1]
    if name not in TASKS:
        raise argparse.ArgumentTypeError(
            f"unknown task {text}; the tasks are {', '.join(sorted(TASKS))} "
            "(see humotion-gym tasks)"
        )
    return name


def add_data_dir(parser: argparse.ArgumentParser) -> None:
    """``--data-dir DIR...``: folders of real mocap (else ``$HUMOTION_MOCAP``, else synthetic)."""
    parser.add_argument(
        "--data-dir", nargs="*", default=None, metavar="DIR",
        help="folders of real mocap (default: $HUMOTION_MOCAP if set, else the synthetic library)",
    )  # fmt: skip


def add_fps(parser: argparse.ArgumentParser) -> None:
    """``--fps``: the frame rate clips are resampled to."""
    parser.add_argument(
        "--fps", type=positive_float, default=30.0,
        help="frame rate the clips are resampled to, Hz (default: 30)",
    )  # fmt: skip


def add_json(parser: argparse.ArgumentParser, what: str = "print JSON instead of a table") -> None:
    """``--json``: machine-readable output."""
    parser.add_argument("--json", action="store_true", help=what)


def add_seed(parser: argparse.ArgumentParser, what: str = "random seed") -> None:
    """``--seed``: a non-negative seed, default 0."""
    parser.add_argument("--seed", type=nonnegative_int, default=0, help=f"{what} (default: 0)")


def add_task(parser: argparse.ArgumentParser, default: str, what: str = "task id") -> None:
    """``--task``: one registered task's id (with or without its namespace)."""
    parser.add_argument(
        "--task", type=task_name, default=default, help=f"{what} (default: {default})"
    )


def env_kwargs(args: argparse.Namespace) -> dict[str, Any]:
    """Keyword arguments of ``gymnasium.make`` from ``--data-dir`` and ``--size``."""
    kwargs: dict[str, Any] = {}
    if getattr(args, "data_dir", None):
        kwargs["data_dir"] = args.data_dir
    if getattr(args, "size", None):
        kwargs["width"], kwargs["height"] = args.size
    return kwargs


def wrote(path: Path | str, what: str = "") -> None:
    """Say where a file was written (every command that writes says so)."""
    print(f"wrote {path}" + (f" ({what})" if what else ""))


def report(args: argparse.Namespace, result: Any, what: str, text: Callable[[], str]) -> int:
    """A command's ending: the result to ``args.out`` as JSON (when given), then JSON or text.

    Args:
        args: The command's arguments (``out``: a path or None; ``json``: a flag).
        result: The JSON-serialisable result.
        what: What the file holds, for the message saying where it was written.
        text: The human-readable report, made only when printed.

    Returns:
        The exit status, 0.
    """
    if args.out:
        args.out.write_text(json.dumps(result, indent=1))
        if not args.json:
            wrote(args.out, what)
    if args.json:
        print_json(result)
    else:
        print(text())
    return 0


def _plain(value: Any) -> Any:
    if hasattr(value, "tolist"):  # numpy scalars and arrays
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"not JSON-serialisable: {type(value).__name__}")


def print_json(obj: Any) -> None:
    """Print one JSON document (numpy values and paths become plain JSON)."""
    print(json.dumps(obj, default=_plain))
