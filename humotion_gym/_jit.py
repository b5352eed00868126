"""numba's compiler for every compiled pass of both packages, its cache kept where it can be.

numba caches each compiled function (``$NUMBA_CACHE_DIR``, else
``__pycache__`` beside the module, else ``~/.cache/numba``), and raises on
import where it can write none (a read-only image with a read-only home).
:func:`compiled` then points the cache at a folder of the user's own under
the temporary folder, once, with a warning naming ``NUMBA_CACHE_DIR``; where
even that cannot be written, the functions are compiled in every process.
"""

from __future__ import annotations

import contextlib
import os
import stat
import tempfile
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numba
from numba.core import config as numba_config

#: numba's message where no cache folder can be written for a function.
_NO_LOCATOR = "cannot cache function"
#: Empty until a function finds no cache folder; then whether the cache moved to the
#: temporary folder.
_moved: list[bool] = []


def _own_temporary_folder() -> str | None:
    """A folder of this user's alone under the system's temporary folder, or None.

    numba unpickles its cache's index files: a folder another user could
    write into (a shared ``/tmp``, where anyone may make a folder of the
    expected name first, or a link to one) would run their code here. So the
    folder must be a real folder (not a link), owned by this user, that no
    one else could ever write into (one others may only read is closed to
    them first); where the usual name is taken by anything else (a file, a
    link, another's folder), a new private folder is made for this process.
    """
    base = Path(tempfile.gettempdir())
    if not hasattr(os, "getuid"):  # Windows: the temporary folder is the user's own
        folder = base / "numba-cache"
        try:
            folder.mkdir(exist_ok=True)
        except OSError:
            return None
        return str(folder)
    folder = base / f"numba-cache-{os.getuid()}"
    try:
        with contextlib.suppress(FileExistsError):  # (a file or a link there: checked below)
            folder.mkdir(mode=0o700)
        info = os.lstat(folder)
        ours = stat.S_ISDIR(info.st_mode) and info.st_uid == os.getuid()
        if ours and not info.st_mode & 0o022:  # nobody else ever wrote there
            if info.st_mode & 0o077:  # but others may read: closed
                os.chmod(folder, 0o700)
        else:  # a file, a link, another's, or one others could write into
            folder = Path(tempfile.mkdtemp(prefix="numba-cache-"))  # mode 0o700, ours
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError:
        return None
    return str(folder)


def _use_temporary_cache() -> bool:
    """Point numba's cache at :func:`_own_temporary_folder` (and say so); False if none."""
    folder = _own_temporary_folder()
    if folder is None:
        warnings.warn(
            "numba can write its cache nowhere (beside humotion_gym, in $NUMBA_CACHE_DIR, "
            "~/.cache or the temporary folder): the compiled passes are compiled again in "
            "every process (seconds); set NUMBA_CACHE_DIR to a writable folder",
            stacklevel=3,
        )
        return False
    given = os.environ.get("NUMBA_CACHE_DIR")
    yours = f"in your NUMBA_CACHE_DIR ({given}), " if given else ""
    warnings.warn(
        f"numba cannot write its cache {yours}beside humotion_gym or in your home: it is "
        f"kept in {folder}; set NUMBA_CACHE_DIR to a writable folder to choose where",
        stacklevel=3,
    )
    # The variable too: numba reloads its settings from the environment, and
    # processes started from this one (Ray's workers, a fit's) inherit it.
    os.environ["NUMBA_CACHE_DIR"] = folder
    setattr(numba_config, "CACHE_DIR", folder)  # noqa: B010  (set by numba from the environment)
    return True


def compiled(**options: Any) -> Callable[[Callable[..., Any]], Any]:
    """``numba.njit(cache=True, nogil=True, **options)``, with a cache wherever one can be.

    ``nogil``: filters and environments on several threads run in parallel.
    Without a writable cache folder the cache moves (:func:`_use_temporary_cache`)
    or is dropped.
    """

    def decorate(function: Callable[..., Any]) -> Any:
        made = _cached(function, options)
        if made is None:
            if not _moved:  # the first function without a cache: move it, once
                _moved.append(_use_temporary_cache())
            if _moved[0]:
                made = _cached(function, options)
        return made if made is not None else numba.njit(nogil=True, **options)(function)

    return decorate


def _cached(function: Callable[..., Any], options: dict[str, Any]) -> Any:
    """``function`` compiled with a cache; None where numba finds no folder for it."""
    try:
        return numba.njit(cache=True, nogil=True, **options)(function)
    except RuntimeError as exc:
        if _NO_LOCATOR not in str(exc):
            raise
        return None
