"""The SHA-256 registry of CMU's files and the checks of a downloaded file against it.

Re-exported by :mod:`humotion_gym.mocap.download`: :class:`RegistryEntry`,
:func:`load_registry`, :func:`record_registry` and :data:`REGISTRY_PATH`.
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from humotion_gym.files import write_text_atomically

#: The packaged registry of SHA-256 and sizes of CMU's files.
REGISTRY_PATH = Path(__file__).resolve().parent / "data" / "cmu_sha256.txt"


# A CMU file's path relative to the download folder: SS/SS.asf or SS/SS_TT.amc.
_CMU_REL = re.compile(r"(\d{2,3})/\1(?:_\d{2,3})?\.(?:asf|amc)")


@dataclass(frozen=True)
class RegistryEntry:
    """What a registered file must be: its SHA-256 (hex) and size in bytes."""

    sha256: str
    bytes: int


def load_registry(path: str | Path | None = None) -> dict[str, RegistryEntry]:
    """Read a registry of SHA-256 and sizes.

    The format is one file per line, ``SHA256 BYTES SS/NAME`` separated by
    spaces (``#`` starts a comment), as :func:`record_registry` writes it.

    Args:
        path: The registry file; the packaged :data:`REGISTRY_PATH` when None.

    Returns:
        Relative path (``01/01_01.amc``) -> :class:`RegistryEntry`.

    Raises:
        FileNotFoundError: If the file does not exist.
        ValueError: If a line is malformed (the message names file and line).
    """
    path = Path(path) if path is not None else REGISTRY_PATH
    out: dict[str, RegistryEntry] = {}
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        why = f"{exc.reason} at byte {exc.start}"
        raise ValueError(f"{path}: not a text registry ({why})") from None
    for n, line in enumerate(text.splitlines(), 1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        parts = line.split()
        if (
            len(parts) != 3
            or not re.fullmatch(r"[0-9a-f]{64}", parts[0])
            or not parts[1].isdigit()
            or not _CMU_REL.fullmatch(parts[2])
        ):
            raise ValueError(f"{path}:{n}: expected 'SHA256 BYTES SS/NAME.asf|amc', got {line!r}")
        out[parts[2]] = RegistryEntry(parts[0], int(parts[1]))
    return out


def record_registry(src: str | Path, out: str | Path | None = None) -> dict[str, RegistryEntry]:
    """Record SHA-256 and sizes of the original CMU files under ``src``.

    ``src`` holds subject folders as CMU lays them out (``src/02/02.asf``,
    ``src/02/02_01.amc``...); other files are ignored. Only record files known
    to be CMU's originals: a download is later refused when it disagrees.

    Args:
        src: The folder of original files (``../shared/mocap/cmu-asfamc``).
        out: Where to write the registry; the packaged :data:`REGISTRY_PATH`
            when None. Entries already there for other files are kept.

    Returns:
        All entries written, by relative path.

    Raises:
        FileNotFoundError: If ``src`` holds no CMU ASF/AMC file.
    """
    src = Path(src)
    out = Path(out) if out is not None else REGISTRY_PATH
    found = {
        p.relative_to(src).as_posix(): p
        for p in sorted(src.glob("*/*"))
        if p.is_file() and _CMU_REL.fullmatch(p.relative_to(src).as_posix())
    }
    if not found:
        raise FileNotFoundError(f"{src}: no CMU files (SS/SS.asf, SS/SS_TT.amc) here")
    entries = load_registry(out) if out.is_file() else {}
    for rel, p in found.items():
        entries[rel] = RegistryEntry(_sha256(p), p.stat().st_size)
    lines = [
        "# SHA-256 and size in bytes of CMU Graphics Lab Motion Capture Database files,",
        f"# recorded from CMU's original ASF/AMC files (a folder named {src.name!r}) by",
        "#   python -m humotion_gym.mocap.download --record-registry DIR",
        "# A downloaded file named here must match it or is refused; see docs/data.md.",
        "# sha256 bytes path",
    ]
    lines += [f"{e.sha256} {e.bytes} {rel}" for rel, e in sorted(entries.items())]
    out.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomically(out, "\n".join(lines) + "\n")
    return entries


def _resolve_registry(
    registry: Mapping[str, RegistryEntry] | str | Path | None,
) -> Mapping[str, RegistryEntry]:
    if registry is None or isinstance(registry, (str, Path)):
        return load_registry(registry)
    return registry


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _check_file(path: Path, entry: Any, expected: RegistryEntry | None) -> str | None:
    """Why ``path`` is not the intact file its manifest entry records (None if it is).

    A file the registry names must also match the registry: the manifest alone
    never vouches for it.
    """
    if not isinstance(entry, dict):
        return "no manifest entry"
    if not path.is_file():
        return "missing"
    size = path.stat().st_size
    # Size first: a cheap test that rules out most damaged files unhashed.
    if expected is not None and size != expected.bytes:
        return f"{size} bytes, the registry says {expected.bytes}"
    if size != entry.get("bytes"):
        return f"{size} bytes, the manifest says {entry.get('bytes')}"
    sha = _sha256(path)
    if expected is not None and sha != expected.sha256:
        return f"SHA-256 {sha}, the registry says {expected.sha256}"
    if sha != entry.get("sha256"):
        return f"SHA-256 {sha}, the manifest says {entry.get('sha256')}"
    return None
