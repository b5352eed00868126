"""Files of the on-disk cache: entry paths, stale entries, problems reported once.

Used for parsed clips (:func:`humotion_gym.mocap.library.load_library`) and
fitted priors; everything here is re-exported by
:mod:`humotion_gym.mocap.library`.
"""

from __future__ import annotations

import contextlib
import os
import warnings
from pathlib import Path

from humotion_gym.mocap.motion import READ_ERRORS


class CacheWarning(UserWarning):
    """A cache entry was unreadable, inconsistent or foreign, or could not be written.

    Raised through :func:`warnings.warn` once per damaged entry, naming the
    file and what was wrong; the entry is rebuilt and overwritten, so loading
    carries on.
    """


#: What reading or writing a cache entry can raise (the same as reading a saved clip).
CACHE_ERRORS: tuple[type[BaseException], ...] = READ_ERRORS


def package_version() -> str:
    """The installed humotion_gym's version (``humotion_gym.__version__``), part of cache keys."""
    from humotion_gym._version import __version__

    return __version__


def report_cache_problem(path: Path, problem: str) -> None:
    """Report a cache entry that is being rebuilt: one :class:`CacheWarning` naming it."""
    warnings.warn(f"humotion_gym cache: {path}: {problem}", CacheWarning, stacklevel=3)


# Cache folders already reported as unwritable in this process: one warning each,
# not one per entry (a run over the shared data would print a thousand).
_UNWRITABLE: set[Path] = set()


def report_unwritten(path: Path, exc: BaseException) -> None:
    """Report an entry that could not be written: once per folder when the folder is the cause.

    A folder that is not one (a file stands there) or cannot be made is reported
    once for the whole process; any other failure, entry by entry.
    """
    folder = path.parent
    if not folder.is_dir():
        if folder not in _UNWRITABLE:
            _UNWRITABLE.add(folder)
            warnings.warn(
                f"humotion_gym cache: {folder} cannot be made ({_why_no_folder(folder, exc)}); "
                "nothing is cached there, so every entry is rebuilt each time",
                CacheWarning,
                stacklevel=3,
            )
        return
    report_cache_problem(path, f"could not write the entry ({exc}); not cached")


def _why_no_folder(folder: Path, exc: BaseException) -> str:
    """Why ``folder`` could not be made, in words: a file in its way, else the OS's reason."""
    blocker = next((p for p in (folder, *folder.parents) if p.exists()), None)
    if blocker is not None and not blocker.is_dir():
        return f"{blocker} is a file, not a folder"
    reason = getattr(exc, "strerror", None) or str(exc)
    return reason[:1].lower() + reason[1:]


def cache_entry_path(folder: Path, stem: str) -> tuple[Path | None, str | None]:
    """Where the cache entry ``stem`` lives in ``folder``, and what blocked its natural name.

    The natural name is ``folder/stem.npz``. A stray empty directory there is
    removed; a non-empty one is left alone and the entry moves to
    ``stem.1.npz`` (``stem.2.npz``... if those are directories too).

    Returns:
        The file to read and write (None when no name is free), and a line to
        report if the entry must be rebuilt (None when the natural name was free).
    """
    path = folder / f"{stem}.npz"
    if not path.is_dir():
        return path, None
    try:
        path.rmdir()
    except OSError:
        pass
    else:
        return path, "a stray empty directory stood at the entry's path; removed it"
    for i in range(1, 10):
        alt = folder / f"{stem}.{i}.npz"
        if not alt.is_dir():
            return alt, f"a non-empty directory stands at {path.name}; using {alt.name}"
    return None, f"directories stand at {path.name} and its alternatives; not caching it"


def placed_entry_path(
    folder: Path, place: str, key: str, legacy: str
) -> tuple[Path | None, str | None]:
    """:func:`cache_entry_path` of ``PLACE-KEY``, an entry named by its place and key.

    The place names what an entry is of (a clip at a frame rate, a prior's fit
    on some data) and the key adds what makes it stale (files' stats, code,
    versions), so :func:`remove_stale_entries` finds the stale ones by their
    place. An entry still under its name from before places (``legacy``) is
    renamed to its place's first, so that it is read, not rebuilt.
    """
    path, blocked = cache_entry_path(folder, f"{place}-{key}")
    old = folder / f"{legacy}.npz"
    if path is not None and not path.exists() and old.is_file():
        with contextlib.suppress(OSError):  # else it is rebuilt, as any missing entry
            os.replace(old, path)
    return path, blocked


def remove_stale_entries(folder: Path, place: str, kept: Path, legacy: str) -> None:
    """Remove the place's entries but ``kept``, and ``legacy``'s (see :func:`placed_entry_path`)."""
    for old in [*folder.glob(f"{place}-*.npz"), folder / f"{legacy}.npz"]:
        if old != kept and old.is_file():
            with contextlib.suppress(OSError):  # another process's, or read-only: left
                old.unlink(missing_ok=True)


def entry_places(folder: Path) -> set[str]:
    """The places of the entries in ``folder`` and the names of its legacy ones.

    A writer of many entries lists the folder once with this, then calls
    :func:`remove_stale_entries` only for a place (or legacy name) found here:
    an entry written after the listing (by another process) is left for its
    own writer to clean.
    """
    try:
        names = os.listdir(folder)
    except OSError:  # no folder, or not one: nothing stale in it
        return set()
    return {n.split("-", 1)[0] if "-" in n else n[:-4] for n in names if n.endswith(".npz")}
