"""``humotion-gym cache``: where the cache is, what it holds, and clearing it.

The cache folder is ``$HUMOTION_CACHE`` if set, else
``$XDG_CACHE_HOME/humotion_gym`` (``~/.cache/humotion_gym``). It holds parsed
clips (``clips/``), fitted priors (``priors/``) and downloads (``cmu/``);
everything but the downloads is rebuilt on demand.

::

    humotion-gym cache info [--json]
    humotion-gym cache clear [--downloads]
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from humotion_gym.cli._common import CommandError, add_command, add_json, print_json

#: Sub-folders rebuilt on demand (``cache clear`` removes them).
REBUILT = ("clips", "priors")
#: Sub-folders of downloaded data (``cache clear --downloads`` removes them too).
DOWNLOADS = ("cmu",)
#: What the cache writes in each part: ``cache clear`` removes these files and no
#: others (a user's file kept there is left, and said so).
OWN_FILES: dict[str, tuple[str, ...]] = {
    "clips": ("*.npz", ".*.tmp"),
    "priors": ("*.npz", ".*.tmp"),
    "cmu": ("*.amc", "*.asf", "*.bvh", "*.part", "*.part.json", "manifest.json", ".*.tmp"),
}


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``cache info`` and ``cache clear``."""
    cache = add_command(
        subparsers, "cache", "the cache of parsed clips, fitted priors and downloads",
        "humotion-gym cache info",
    )  # fmt: skip
    csub = cache.add_subparsers(dest="cache_command", required=True, metavar="COMMAND")
    info = add_command(
        csub, "info", "where the cache is and the size of each part",
        "humotion-gym cache info --json",
    )  # fmt: skip
    add_json(info, "one JSON object instead of lines")
    info.set_defaults(func=_cmd_info)
    clear = add_command(
        csub, "clear", "remove parsed clips and fitted priors (rebuilt on demand)",
        "humotion-gym cache clear",
    )  # fmt: skip
    clear.add_argument(
        "--downloads", action="store_true", help="also remove downloaded mocap (cmu/)"
    )
    clear.set_defaults(func=_cmd_clear)


def _size(path: Path) -> tuple[int, int]:
    """Files and bytes under a folder (0, 0 when absent)."""
    if not path.is_dir():
        return 0, 0
    files = [p for p in path.rglob("*") if p.is_file() and not p.is_symlink()]
    return len(files), sum(p.stat().st_size for p in files)


def _cache_root() -> Path:
    """The cache folder; refused when a file stands where it should be.

    Raises:
        CommandError: Naming ``$HUMOTION_CACHE`` when it was set to a file.
    """
    from humotion_gym.mocap.library import CACHE_ENV, default_cache_dir

    root = default_cache_dir()
    if root.exists() and not root.is_dir():
        where = f"${CACHE_ENV}" if _from_env() else "the default cache folder"
        raise CommandError(f"{where}: {root} is a file, expected a folder")
    return root


def _cmd_info(args: argparse.Namespace) -> int:
    from humotion_gym.mocap.library import CACHE_ENV

    root = _cache_root()
    parts = {name: _size(root / name) for name in REBUILT + DOWNLOADS}
    if args.json:
        print_json({
            "path": str(root), "set_by": CACHE_ENV if _from_env() else "default",
            "parts": {k: {"files": n, "bytes": b} for k, (n, b) in parts.items()},
        })  # fmt: skip
        return 0
    how = f"${CACHE_ENV}" if _from_env() else f"default; set ${CACHE_ENV} to move it"
    print(f"cache: {root} ({how})")
    for name, (n, b) in parts.items():
        kind = "downloads, kept by cache clear" if name in DOWNLOADS else "rebuilt on demand"
        print(f"  {name + '/':8s} {n:6d} files {b / 2**20:9.1f} MiB  ({kind})")
    return 0


def _from_env() -> bool:
    from humotion_gym.mocap.library import CACHE_ENV

    return bool(os.environ.get(CACHE_ENV))


def _cmd_clear(args: argparse.Namespace) -> int:
    root = _cache_root()
    names = REBUILT + (DOWNLOADS if args.downloads else ())
    freed = removed = 0
    for name in names:
        folder = root / name
        if not folder.is_dir():
            continue
        own, foreign = _own_files(folder, OWN_FILES[name])
        for path in own:
            # a link (even one whose file is gone) is removed, not what it points to
            freed += 0 if path.is_symlink() else path.stat().st_size
            path.unlink()
        removed += len(own)
        _remove_empty_folders(folder)
        if own:
            print(f"removed {len(own)} files from {folder}")
        if foreign:  # the user's files in a folder the cache uses: never removed
            print(
                f"left {len(foreign)} files in {folder} that the cache did not write "
                f"(e.g. {foreign[0].name})"
            )
    if not removed:
        print(f"nothing to remove in {root}")
    else:
        print(f"freed {freed / 2**20:.1f} MiB")
    return 0


def _own_files(folder: Path, patterns: tuple[str, ...]) -> tuple[list[Path], list[Path]]:
    """The files under ``folder`` the cache wrote (by ``patterns``) and the others."""
    files = sorted(p for p in folder.rglob("*") if p.is_file() or p.is_symlink())
    own: list[Path] = []
    foreign: list[Path] = []
    for path in files:
        (own if any(path.match(pattern) for pattern in patterns) else foreign).append(path)
    return own, foreign


def _remove_empty_folders(folder: Path) -> None:
    """Remove ``folder`` and the folders under it that are left empty, deepest first."""
    for path in sorted(folder.rglob("*"), key=lambda p: len(p.parts), reverse=True) + [folder]:
        if path.is_dir() and not path.is_symlink() and not any(path.iterdir()):
            path.rmdir()
