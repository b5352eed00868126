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
import contextlib
import errno
import json
import math
import os
import tempfile
import textwrap
import warnings
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

from humotion_gym.envs._checks import FPS_RANGE
from humotion_gym.files import json_default, write_text_atomically
from humotion_gym.render_scene import MAX_IMAGE_SIZE, MIN_IMAGE_SIZE


class UsageError(ValueError):
    """A command's arguments are wrong together (exit 2); the message names the flag."""


class CommandError(RuntimeError):
    """A command could not do its work for a reason the user can fix (exit 1)."""


@contextlib.contextmanager
def refused_as(
    error: type[Exception],
    kinds: type[BaseException] | tuple[type[BaseException], ...],
    prefix: str = "",
) -> Iterator[None]:
    """Raise ``error`` with ``prefix`` and the message of an exception of ``kinds`` in the block.

    How a command turns a refusal of what it called into its own error and
    exit code (:class:`UsageError` 2, :class:`CommandError` 1, or argparse's
    ``ArgumentTypeError``), the flag named in ``prefix`` (e.g. ``"--agent: "``);
    other exceptions pass unchanged, and the refusal's traceback is dropped.
    """
    try:
        yield
    except kinds as exc:
        raise error(f"{prefix}{exc}") from None


#: The most memory a command may plan to hold for frames it renders or synthesises
#: (``check_memory``); a request beyond it is refused before anything is allocated.
MEMORY_BUDGET_BYTES: int = 2 << 30
#: The most episodes per cell or run (each is seconds of tracking at least).
MAX_EPISODES: int = 10_000


def _number(kind: type, text: str) -> Any:
    try:
        value = kind(text)
    except (ValueError, OverflowError):
        what = "an integer" if kind is int else "a number"
        raise argparse.ArgumentTypeError(f"expected {what}, got {text[:40]!r}") from None
    if kind is float and not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text[:40]!r}")
    return value


def int_at_least(low: int, high: int | None = None) -> Callable[[str], int]:
    """An argparse ``type`` accepting integers ``>= low`` (and ``<= high`` when given)."""

    def parse(text: str) -> int:
        value = _number(int, text)
        if value < low or (high is not None and value > high):
            bound = f"between {low} and {high:,}" if high is not None else f">= {low}"
            raise argparse.ArgumentTypeError(f"expected an integer {bound}, got {text}")
        return value

    parse.__name__ = f"integer >= {low}"
    return parse


def float_between(low: float, high: float, *, open_low: bool = False) -> Callable[[str], float]:
    """An argparse ``type`` accepting finite numbers in ``[low, high]`` (``(low, high]``)."""

    def parse(text: str) -> float:
        value = _number(float, text)
        if value < low or value > high or (open_low and value == low):
            left = "(" if open_low else "["
            raise argparse.ArgumentTypeError(
                f"expected a number in {left}{low:g}, {high:g}], got {text}"
            )
        return value

    parse.__name__ = "number"
    return parse


#: ``type=`` for counts that must be at least one (episodes, particles, frames...).
positive_int = int_at_least(1)
#: ``type=`` for seeds and other counts that may be zero (seeds: numpy's 32-bit range
#: is not the limit, numpy takes any non-negative integer).
nonnegative_int = int_at_least(0)
#: ``type=`` for episode counts.
episode_count = int_at_least(1, MAX_EPISODES)


def positive_float(text: str) -> float:
    """An argparse ``type`` accepting finite numbers ``> 0``."""
    value = _number(float, text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {text}")
    return value


def probability(text: str) -> float:
    """An argparse ``type`` accepting numbers in ``(0, 1)``."""
    value = _number(float, text)
    if not 0 < value < 1:
        raise argparse.ArgumentTypeError(f"expected a number between 0 and 1, got {text}")
    return value


def image_size(text: str) -> tuple[int, int]:
    """An argparse ``type`` for ``WIDTHxHEIGHT`` (e.g. ``256x256``) that the renderer draws."""
    parts = text.lower().split("x")
    try:
        width, height = (int(p) for p in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected WIDTHxHEIGHT, e.g. 256x256, got {text[:40]!r}"
        ) from None
    (w0, h0), (w1, h1) = MIN_IMAGE_SIZE, MAX_IMAGE_SIZE
    if not (w0 <= width <= w1 and h0 <= height <= h1):
        raise argparse.ArgumentTypeError(
            f"expected WIDTHxHEIGHT from {w0}x{h0} to {w1}x{h1}, got {text[:40]}"
        )
    return width, height


def check_memory(flag: str, count: int, bytes_each: int, what: str) -> None:
    """Refuse a request whose ``count x bytes_each`` exceeds :data:`MEMORY_BUDGET_BYTES`.

    Raises:
        UsageError: Naming ``flag``, the bytes asked for and the largest count that fits.
    """
    if count * bytes_each > MEMORY_BUDGET_BYTES:
        most = MEMORY_BUDGET_BYTES // max(bytes_each, 1)
        raise UsageError(
            f"{flag}: {count:,} {what} would take {count * bytes_each / 2**30:.1f} GiB "
            f"(the limit is {MEMORY_BUDGET_BYTES / 2**30:g} GiB: at most {most:,})"
        )


def _writable_folder(folder: Path) -> str | None:
    """Why files cannot be created in ``folder`` or the folder it would be made in, or None."""
    probe = folder
    while not probe.exists():
        if probe.is_symlink() or probe.parent == probe:
            return f"{probe} cannot be created"
        probe = probe.parent
    if not probe.is_dir():
        return f"{probe} is a file, not a folder"
    try:
        with tempfile.TemporaryFile(dir=probe):
            pass
    except OSError as exc:
        reason = str(exc.strerror or exc)
        reason = reason[:1].lower() + reason[1:]
        if exc.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
            return f"{probe} is not writable ({reason})"
        # another refusal (/proc says "no such file or directory"): the OS's
        # words as its own, since "not writable (no such file)" contradicts itself
        return f"files cannot be created in {probe} (the system says: {reason})"
    return None


class OutputFile(type(Path())):  # type: ignore[misc]
    """A file a command will write, checked by :func:`output_file` when parsed.

    Its missing folders are made before the command starts (:func:`make_output_folders`).
    """


class OutputFolder(type(Path())):  # type: ignore[misc]
    """A folder a command writes into, checked by :func:`output_dir` when parsed.

    While the command runs it holds the folder alone (:func:`hold_output_folders`).
    """


@contextlib.contextmanager
def hold_output_folders(args: argparse.Namespace) -> Iterator[None]:
    """Make each :class:`OutputFolder` argument and hold it for this command alone meanwhile.

    Two commands writing into one folder at once would interleave their
    files. Each folder is locked with ``flock`` on the folder itself (the
    lock goes with the process however it ends); where it cannot be (NFS,
    Lustre, a folder one may write but not read) the command runs unheld,
    saying so (silently on Windows, which has no ``fcntl``).

    Raises:
        UsageError: Naming the flag and the folder another command holds.
    """
    try:
        import fcntl
    except ImportError:  # pragma: no cover - Windows
        yield
        return
    with contextlib.ExitStack() as held:
        seen: set[Path] = set()
        for name, value in vars(args).items():
            if not isinstance(value, OutputFolder) or value.resolve() in seen:
                continue
            seen.add(value.resolve())
            missing = [f for f in (value, *value.parents) if not f.exists()]
            value.mkdir(parents=True, exist_ok=True)
            held.callback(_remove_empty, missing)  # a command that wrote nothing leaves none
            try:
                fd = os.open(value, os.O_RDONLY)
            except OSError as exc:  # a folder one may write into but not read
                _unheld(value, exc)
                continue
            held.callback(os.close, fd)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                flag = "--" + name.replace("_", "-")
                raise UsageError(
                    f"{flag}: another humotion-gym command is writing into {value}; wait for "
                    "it to end or choose another folder"
                ) from None
            except OSError as exc:  # a file system without flock (NFS, Lustre): run unheld
                _unheld(value, exc)
        yield


@contextlib.contextmanager
def hold_default_folder(path: Path, dest: str) -> Iterator[None]:
    """:func:`hold_output_folders` for the folder a command chooses when flag ``dest`` is not given.

    Checked as :func:`output_dir` checks the flag's value, and refused in its name.

    Raises:
        UsageError: If the folder cannot be written or another command holds it.
    """
    with refused_as(UsageError, argparse.ArgumentTypeError, f"--{dest.replace('_', '-')}: "):
        folder = output_dir(str(path))
    with hold_output_folders(argparse.Namespace(**{dest: folder})):
        yield


def _unheld(folder: Path, exc: OSError) -> None:
    """Say that ``folder`` runs without being held (:func:`hold_output_folders`)."""
    warnings.warn(
        f"{folder} cannot be held for this command alone ({exc.strerror or exc}): a second "
        "command writing into it meanwhile would not be refused",
        RuntimeWarning,
        stacklevel=4,
    )


def _remove_empty(folders: Sequence[Path]) -> None:
    """Remove those of ``folders`` (innermost first) that are still empty."""
    for folder in folders:
        with contextlib.suppress(OSError):  # not empty, or gone: left as it is
            folder.rmdir()


def make_output_folders(args: argparse.Namespace) -> None:
    """Create the missing folders of the command's :class:`OutputFile` arguments."""
    for value in vars(args).values():
        if isinstance(value, OutputFile):
            value.parent.mkdir(parents=True, exist_ok=True)


def output_file(*suffixes: str) -> Callable[[str], Path]:
    """An argparse ``type`` for a file to write: checked before any work is done.

    Refuses a folder, a suffix other than ``suffixes`` (when given) and a
    place where the file cannot be created (a file in the way, no permission,
    a read-only file system). Nothing is created while parsing; the file's
    missing folders are made before the command starts (an :class:`OutputFile`).
    """

    def parse(text: str) -> Path:
        path = Path(text)
        if not text.strip():
            raise argparse.ArgumentTypeError("expected a file name, got an empty one")
        if suffixes and path.suffix.lower() not in suffixes:
            raise argparse.ArgumentTypeError(
                f"expected a {' or '.join(suffixes)} file, got {text[:80]}"
            )
        if path.is_dir():
            raise argparse.ArgumentTypeError(f"{text}: is a folder, expected a file")
        problem = _writable_folder(path.parent)
        if problem is None and path.exists() and not os.access(path, os.W_OK):
            problem = f"{path} is not writable"
        if problem:
            raise argparse.ArgumentTypeError(f"cannot write {text[:80]}: {problem}")
        return OutputFile(text)

    parse.__name__ = "output file"
    return parse


def check_output_file(path: Path, flag: str, *suffixes: str) -> Path:
    """:func:`output_file`'s check of a path a command derived itself (a default).

    Raises:
        UsageError: Naming ``flag``, if the file cannot be written there.
    """
    with refused_as(UsageError, argparse.ArgumentTypeError, f"{flag}: "):
        return output_file(*suffixes)(str(path))


def output_dir(text: str) -> Path:
    """An argparse ``type`` for a folder to write into (made if needed), checked first."""
    path = Path(text)
    if not text.strip():
        raise argparse.ArgumentTypeError("expected a folder name, got an empty one")
    if path.exists() and not path.is_dir():
        raise argparse.ArgumentTypeError(f"{text}: is a file, expected a folder")
    problem = _writable_folder(path)
    if problem:
        raise argparse.ArgumentTypeError(f"cannot write into {text[:80]}: {problem}")
    return OutputFolder(path)


def shared_output_dir(text: str) -> Path:
    """:func:`output_dir`, not held: other commands may write their own files into it meanwhile.

    E.g. ``train --export``: trainings put their policies into one folder, each under its name.
    """
    return Path(output_dir(text))


class Distinct(argparse.Action):
    """A list flag's values, each once, in the order given (``--agents a a`` runs ``a`` once)."""

    def __call__(
        self,
        parser: argparse.ArgumentParser,
        namespace: argparse.Namespace,
        values: Any,
        option_string: str | None = None,
    ) -> None:
        setattr(namespace, self.dest, list(dict.fromkeys(values)))


def check_fresh_output(out: Path, names: Sequence[str], what: str, flag: str = "--out") -> None:
    """Refuse a folder that already holds a run's results, before the run starts.

    A rerun into the folder of a recorded result (a sweep, trained weights) would replace it.

    Raises:
        UsageError: Naming the flag, the folder and the file found.
    """
    found = [name for name in names if (out / name).exists()]
    if found:
        raise UsageError(
            f"{flag}: {out} already holds {what} ({found[0]}); choose another folder or move "
            "it away"
        )


def check_mocap_paths(paths: Sequence[str | Path], flag: str) -> None:
    """Refuse paths that hold no motion capture before a command starts its work.

    Raises:
        FileNotFoundError: If a path does not exist.
        MocapFormatError: If a file is not BVH or AMC, or two would be one clip.
        CommandError: If the paths hold no clip at all, naming ``flag``.
    """
    from humotion_gym.mocap.library import find_clips

    # say which flag (or variable) named the path
    with refused_as(CommandError, FileNotFoundError, f"{flag}: "):
        found = find_clips(paths)
    if not found:
        shown = ", ".join(str(p) for p in paths)
        raise CommandError(f"{flag}: no BVH or ASF/AMC motion capture under {shown[:200]}")


def task_name(text: str) -> str:
    """An argparse ``type`` for a task id (``ArmTrack-v2``, also with ``humotion_gym/``)."""
    from humotion_gym.envs.tasks import TASKS, VIEW_VARIANTS

    name = text.split("/")[-1].split(":")[-1]
    if name not in TASKS and name not in VIEW_VARIANTS:
        raise argparse.ArgumentTypeError(
            f"unknown task {text}; the tasks are "
            f"{', '.join(sorted(TASKS) + sorted(VIEW_VARIANTS))}, described by humotion-gym tasks"
        )
    return name


def add_data_dir(parser: argparse.ArgumentParser) -> None:
    """``--data-dir DIR...``: folders of real mocap (else ``$HUMOTION_MOCAP``, else synthetic).

    At least one folder follows the flag: a bare ``--data-dir`` is a usage
    error, never the synthetic set. ``humotion-gym`` checks the folders hold
    mocap before the command runs (:func:`check_mocap_paths`).
    """
    parser.add_argument(
        "--data-dir", nargs="+", default=None, metavar="DIR",
        help="folders of real mocap (default: $HUMOTION_MOCAP if set, else the synthetic library)",
    )  # fmt: skip


def add_fps(parser: argparse.ArgumentParser) -> None:
    """``--fps``: the frame rate clips are resampled to."""
    parser.add_argument(
        "--fps", type=float_between(*FPS_RANGE), default=30.0,
        help=f"frame rate the clips are resampled to, {FPS_RANGE[0]:g} to {FPS_RANGE[1]:g} Hz "
        "(default: 30)",
    )  # fmt: skip


def add_json(parser: argparse.ArgumentParser, what: str = "print JSON instead of a table") -> None:
    """``--json``: machine-readable output."""
    parser.add_argument("--json", action="store_true", help=what)


def add_seed(parser: argparse.ArgumentParser, what: str = "random seed") -> None:
    """``--seed``: a non-negative seed, default 0."""
    add_int(parser, "--seed", 0, what, nonnegative_int)


def add_int(
    parser: argparse.ArgumentParser,
    flag: str,
    default: int,
    what: str,
    kind: Callable[[str], int] = positive_int,
    **kwargs: Any,
) -> None:
    """An integer ``flag`` read by ``kind``, its help ``what`` then ``(default: N)``.

    ``kwargs`` go on to ``add_argument`` (``metavar``...).
    """
    help_text = f"{what} (default: {default})"
    parser.add_argument(flag, type=kind, default=default, help=help_text, **kwargs)


def add_task(
    parser: argparse.ArgumentParser,
    default: str,
    what: str = "task id",
    kind: Callable[[str], str] = task_name,
) -> None:
    """``--task``: one registered task's id (with or without its namespace), read by ``kind``."""
    parser.add_argument("--task", type=kind, default=default, help=f"{what} (default: {default})")


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


def add_report_out(parser: argparse.ArgumentParser, what: str = "the result") -> None:
    """``--out FILE.json`` and ``--json``: the flags :func:`report` reads."""
    parser.add_argument(
        "--out", type=output_file(".json"), default=None,
        help=f"also write {what} as JSON to this file (default: none)",
    )  # fmt: skip
    add_json(parser)


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
        write_text_atomically(args.out, json_text(result, indent=1))
        if not args.json:
            wrote(args.out, what)
    if args.json:
        print_json(result)
    else:
        print(text())
    return 0


def _finite(value: Any) -> Any:
    """``value`` with numpy values made plain and every NaN or infinity made None (null)."""
    if hasattr(value, "tolist"):
        value = value.tolist()
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    return value


def json_text(obj: Any, indent: int | None = None) -> str:
    """One strict JSON document: numpy values and paths plain, NaN and infinities null.

    Python's ``json`` would write ``NaN``, which JSON does not have and strict
    parsers refuse.
    """
    return json.dumps(_finite(obj), default=json_default, indent=indent, allow_nan=False)


def print_json(obj: Any) -> None:
    """Print one JSON document (see :func:`json_text`)."""
    print(json_text(obj))


def add_command(
    subparsers: argparse._SubParsersAction,
    name: str,
    summary: str,
    example: str,
    details: str = "",
    **kwargs: Any,
) -> argparse.ArgumentParser:
    """Add a sub-command whose help opens with a sentence and ends with one example.

    Args:
        subparsers: From ``add_subparsers``.
        name: The command's name.
        summary: One line, lower case, no full stop: the listing's help, and (as a
            sentence) the first line of the command's own ``--help``.
        example: One command line, from ``humotion-gym`` on.
        details: More paragraphs for the command's ``--help`` (default: none).
        **kwargs: Passed on to ``add_parser``.

    Returns:
        The command's parser.
    """
    sentence = summary[:1].upper() + summary[1:] + ("" if summary.endswith(".") else ".")
    text = "\n\n".join(textwrap.fill(p, 78) for p in (sentence, details) if p)
    return subparsers.add_parser(
        name, help=summary, description=text, epilog=f"example:\n  {example}",
        formatter_class=argparse.RawDescriptionHelpFormatter, **kwargs,
    )  # fmt: skip
