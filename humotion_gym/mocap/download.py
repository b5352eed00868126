"""Download the CMU Graphics Lab Motion Capture Database (ASF/AMC) into a cache.

:func:`download_cmu` fetches the skeleton (``SS.asf``) and every trial
(``SS_TT.amc``) of the requested subjects from CMU's public layout
(``{base_url}/{SS}/{SS}.asf``, ``{base_url}/{SS}/{SS}_{TT}.amc``) into
``dest/{SS}/``, the same layout the motion library loads.

Downloads are resumable and atomic: bytes stream into ``name.part``; a dropped
connection or a short read is retried with an HTTP ``Range`` header from the
bytes already written, and a later call resumes any ``.part`` left behind. Only
a complete file is renamed to its final name, so the library (which ignores
``*.part``) never loads half a clip. Every finished file is recorded with its
SHA-256 in ``dest/manifest.json``; :func:`verify_cache` re-checks them.

Only the standard library speaks HTTP (no extra dependency); tqdm draws the
progress bars.
"""

from __future__ import annotations

import contextlib
import hashlib
import http.client
import json
import operator
import os
import re
import tempfile
import time
import urllib.error
import urllib.request
from collections.abc import Sequence
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from tqdm.auto import tqdm

from humotion_gym.mocap.library import default_cache_dir

__all__ = [
    "CMU_BASE_URL",
    "MANIFEST_NAME",
    "DownloadError",
    "cmu_subject_code",
    "default_cache_dir",
    "download_cmu",
    "list_cmu_trials",
    "verify_cache",
]

#: Where CMU serves its subjects' ASF/AMC files.
CMU_BASE_URL = "http://mocap.cs.cmu.edu/subjects"
#: The manifest of finished files, at the top of the download folder.
MANIFEST_NAME = "manifest.json"
#: Suffix of a file still being downloaded.
PART_SUFFIX = ".part"
#: Seconds to wait before the first retry; doubles with each retry (capped at 8 s)
#: so a briefly overloaded server is not hammered. Tests set it to 0.
RETRY_BACKOFF_S = 1.0

_CHUNK = 1 << 16
# A listing is a small HTML page; the cap keeps a misbehaving server from
# feeding us an endless body.
_MAX_LISTING_BYTES = 8 << 20
# Probing stops here even if a server answers every URL (CMU's largest subject
# has well under a hundred trials).
_MAX_TRIALS = 999
_USER_AGENT = "humotion_gym-download/1 (+urllib)"
# Statuses worth another attempt; any other HTTP error is final (a 403 or 410
# will not change by asking again).
_RETRY_STATUSES = frozenset({408, 425, 429, 500, 502, 503, 504})


class DownloadError(ValueError):
    """A file could not be downloaded.

    Attributes:
        url: The URL that failed.
        status: The HTTP status if the server answered with an error, else None.
        received: Bytes of the file held locally (in its ``.part``) when giving up.
    """

    def __init__(
        self, url: str, reason: str, *, status: int | None = None, received: int = 0
    ) -> None:
        self.url = url
        self.status = status
        self.received = received
        super().__init__(f"{url}: {reason}")


class _ShortRead(OSError):
    """The connection ended before the announced Content-Length was reached."""


def cmu_subject_code(subject: int) -> str:
    """The CMU folder name of a subject: two digits, three from subject 100 on.

    Raises:
        TypeError: If ``subject`` is not an integer.
        ValueError: If ``subject`` is outside 1..999.
    """
    if isinstance(subject, bool):
        # bool is an int subclass; True as "subject 1" is almost surely a bug.
        raise TypeError(f"subjects: expected integers, got {subject!r}")
    try:
        n = operator.index(subject)
    except TypeError:
        raise TypeError(f"subjects: expected integers, got {subject!r}") from None
    if not 1 <= n <= 999:
        raise ValueError(f"subjects: CMU subject numbers are 1..999, got {n}")
    return f"{n:02d}"


def _subject_url(base_url: str, code: str) -> str:
    return f"{base_url.rstrip('/')}/{code}/"


def _open(url: str, timeout: float, headers: dict[str, str] | None = None) -> Any:
    req = urllib.request.Request(url, headers={"User-Agent": _USER_AGENT, **(headers or {})})
    return urllib.request.urlopen(req, timeout=timeout)  # noqa: S310 (http(s) URLs only)


def _trials_from_listing(html: str, code: str) -> list[int]:
    # Accept relative ("02_01.amc"), rooted ("/subjects/02/02_01.amc") and
    # absolute hrefs, quoted or not, as Apache and http.server write them.
    pattern = re.compile(
        rf"""href\s*=\s*["']?(?:[^"'\s>]*/)?{code}_(\d+)\.amc(?=["'\s>?#])""", re.IGNORECASE
    )
    return sorted({int(m) for m in pattern.findall(html)})


def list_cmu_trials(subject: int, base_url: str = CMU_BASE_URL, timeout: float = 30.0) -> list[int]:
    """The trial numbers of a subject, read from the folder's HTML listing.

    Args:
        subject: CMU subject number (1..999).
        base_url: Where the subject folders are.
        timeout: Socket timeout in seconds.

    Returns:
        Sorted trial numbers, or an empty list when the listing cannot be had or
        names no trial (the caller then probes trial numbers instead).
    """
    code = cmu_subject_code(subject)
    try:
        with _open(_subject_url(base_url, code), timeout) as resp:
            raw = resp.read(_MAX_LISTING_BYTES)
            charset = resp.headers.get_content_charset() or "utf-8"
    except (OSError, http.client.HTTPException, ValueError):
        # No listing (404, listings disabled, network trouble): probing follows.
        return []
    return _trials_from_listing(raw.decode(charset, errors="replace"), code)


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _read_manifest(dest: Path) -> dict[str, dict[str, Any]]:
    path = dest / MANIFEST_NAME
    if not path.is_file():
        return {}
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        # The manifest is written atomically, so this is outside damage; an
        # empty manifest only means every file is fetched and verified again.
        return {}
    return data if isinstance(data, dict) else {}


def _write_atomic(path: Path, text: str) -> None:
    # Write a sibling temp file then rename: readers see the old or the new
    # manifest, never a torn one.
    fd, tmp = tempfile.mkstemp(prefix=path.name + ".", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def _write_manifest(dest: Path, manifest: dict[str, dict[str, Any]]) -> None:
    _write_atomic(dest / MANIFEST_NAME, json.dumps(manifest, indent=1, sort_keys=True) + "\n")


def _is_complete(path: Path, entry: dict[str, Any] | None) -> bool:
    if not entry or not path.is_file():
        return False
    # Size first: a cheap test that rules out most damaged files unhashed.
    if path.stat().st_size != entry.get("bytes"):
        return False
    return _sha256(path) == entry.get("sha256")


def _parse_content_range(value: str | None) -> tuple[int, int | None] | None:
    """``bytes START-END/TOTAL`` -> (START, TOTAL or None); None if unparsable."""
    m = re.fullmatch(r"\s*bytes\s+(\d+)-(\d+)/(\d+|\*)\s*", value or "")
    if not m:
        return None
    return int(m[1]), (int(m[3]) if m[3] != "*" else None)


def _fetch(url: str, target: Path, *, retries: int, timeout: float, progress: bool) -> int:
    """Download ``url`` to ``target`` through ``target.part``; return its size.

    Raises:
        DownloadError: On a final HTTP error, or when ``retries`` attempts failed.
    """
    part = target.with_name(target.name + PART_SUFFIX)
    failures = 0
    restarted_416 = False
    last = ""
    with tqdm(
        desc=target.name,
        unit="B",
        unit_scale=True,
        unit_divisor=1024,
        leave=False,
        disable=not progress,
    ) as bar:
        while True:
            have = part.stat().st_size if part.exists() else 0
            headers = {"Range": f"bytes={have}-"} if have else {}
            try:
                with _open(url, timeout, headers) as resp:
                    total = _stream(resp, part, have, bar)
                if total is not None and part.stat().st_size != total:
                    raise _ShortRead(f"got {part.stat().st_size} of {total} bytes")
                break
            except urllib.error.HTTPError as e:
                e.close()
                if e.code == 416 and have and not restarted_416:
                    # Our .part is at or past the end of the file on the server
                    # (the file changed, or the .part is stale): start over once.
                    part.unlink()
                    restarted_416 = True
                    continue
                if e.code not in _RETRY_STATUSES:
                    raise DownloadError(
                        url, f"HTTP {e.code} {e.reason}", status=e.code, received=have
                    ) from e
                last = f"HTTP {e.code} {e.reason}"
            except (OSError, http.client.HTTPException) as e:
                # URLError, timeouts, resets, IncompleteRead and our _ShortRead
                # all mean "try again from where we are".
                last = str(getattr(e, "reason", None) or e) or type(e).__name__
            failures += 1
            if failures >= retries:
                received = part.stat().st_size if part.exists() else 0
                raise DownloadError(
                    url,
                    f"failed after {failures} attempt{'s' * (failures != 1)} "
                    f"({received} bytes received, kept in {part.name}): {last}",
                    received=received,
                )
            time.sleep(min(RETRY_BACKOFF_S * 2 ** (failures - 1), 8.0))
    size = part.stat().st_size
    os.replace(part, target)
    return size


def _stream(resp: Any, part: Path, have: int, bar: tqdm) -> int | None:
    """Write a response body into ``part``; return the full file size if known."""
    length = resp.headers.get("Content-Length")
    length = int(length) if length and length.isdigit() else None
    if resp.status == 206:
        rng = _parse_content_range(resp.headers.get("Content-Range"))
        if rng is None or rng[0] != have:
            # A range we did not ask for cannot be appended safely; the next
            # attempt starts from zero instead.
            part.unlink(missing_ok=True)
            raise _ShortRead(f"unexpected Content-Range {resp.headers.get('Content-Range')!r}")
        start, total = have, rng[1]
        if total is None and length is not None:
            total = have + length
        mode = "ab"
    else:
        # 200 to a Range request: the server ignores ranges, so the body is the
        # whole file and the .part must be rewritten from zero.
        start, total, mode = 0, length, "wb"
    bar.reset(total=total)
    bar.update(start)
    with part.open(mode) as f:
        while True:
            # read1, not read: read(n) waits for all n bytes, so on a stall the
            # bytes already received would be lost to the timeout instead of
            # being kept for the resume.
            chunk = resp.read1(_CHUNK)
            if not chunk:
                break
            f.write(chunk)
            bar.update(len(chunk))
        f.flush()
        # On disk before the rename, so a crash cannot leave a final-named file
        # with missing blocks.
        os.fsync(f.fileno())
    return total


def _download_one(
    url: str,
    dest: Path,
    rel: str,
    manifest: dict[str, dict[str, Any]],
    *,
    retries: int,
    timeout: float,
    progress: bool,
) -> tuple[Path, bool]:
    """Fetch one file unless the manifest says it is complete; (path, fetched)."""
    target = dest / rel
    if _is_complete(target, manifest.get(rel)):
        return target, False
    target.parent.mkdir(parents=True, exist_ok=True)
    # Drop the stale entry and any unverified file at the final name first: if
    # the download then fails, no final-named file is left that the manifest
    # does not vouch for (the library would load it as a clip).
    manifest.pop(rel, None)
    target.unlink(missing_ok=True)
    size = _fetch(url, target, retries=retries, timeout=timeout, progress=progress)
    manifest[rel] = {
        "sha256": _sha256(target),
        "bytes": size,
        "url": url,
        "downloaded_at": datetime.now(timezone.utc).isoformat(timespec="seconds"),
    }
    return target, True


def download_cmu(
    subjects: Sequence[int],
    dest: Path | None = None,
    base_url: str = CMU_BASE_URL,
    progress: bool = True,
    retries: int = 3,
    timeout: float = 30.0,
) -> list[Path]:
    """Download the ASF skeleton and every AMC trial of CMU subjects.

    Files land in ``dest/{SS}/`` (``SS`` the two- or three-digit subject
    number), the layout :func:`humotion_gym.mocap.library.load_library` reads.
    A subject's trials come from the HTML listing of ``{base_url}/{SS}/``; when
    there is none, trial numbers 1, 2, 3... are tried until the first 404.
    Files already complete (in the manifest with matching size and SHA-256) are
    not fetched again; ``.part`` files of earlier calls are resumed.

    Args:
        subjects: CMU subject numbers (1..999); duplicates are fetched once.
        dest: Download folder; ``default_cache_dir() / "cmu"`` when None.
        base_url: Where the subject folders are served.
        progress: Show a tqdm bar (bytes) per file; silent when False.
        retries: Attempts per file before giving up (at least 1).
        timeout: Socket timeout in seconds, per connect and per read.

    Returns:
        The paths of all the subjects' files, skipped ones included: per
        subject the ASF, then the AMC files by trial number.

    Raises:
        ValueError: If a subject number is outside 1..999, or ``retries`` < 1.
        TypeError: If a subject number is not an integer.
        DownloadError: If a subject does not exist (its ASF gives HTTP 404), or
            a file still fails after ``retries`` attempts.

    Example:
        >>> paths = download_cmu([2], progress=False)  # doctest: +SKIP
    """
    if isinstance(subjects, int):
        subjects = [subjects]  # a lone subject number is an easy slip to forgive
    # Validate everything before the first request so a typo fails fast.
    codes = list(dict.fromkeys(cmu_subject_code(s) for s in subjects))
    if retries < 1:
        raise ValueError(f"retries: need at least 1 attempt, got {retries}")
    dest = Path(dest) if dest is not None else default_cache_dir() / "cmu"
    dest.mkdir(parents=True, exist_ok=True)
    manifest = _read_manifest(dest)
    opts = {"retries": retries, "timeout": timeout, "progress": progress}
    out: list[Path] = []
    try:
        for code in codes:
            subject_url = _subject_url(base_url, code)
            try:
                path, _ = _download_one(
                    subject_url + f"{code}.asf", dest, f"{code}/{code}.asf", manifest, **opts
                )
            except DownloadError as e:
                if e.status == 404:
                    raise DownloadError(
                        e.url, f"CMU subject {int(code)} not found (HTTP 404)", status=404
                    ) from None
                raise
            out.append(path)
            trials = list_cmu_trials(int(code), base_url, timeout)
            if trials:
                for t in trials:
                    name = f"{code}_{t:02d}.amc"
                    path, _ = _download_one(
                        subject_url + name, dest, f"{code}/{name}", manifest, **opts
                    )
                    out.append(path)
            else:
                out.extend(_probe_trials(code, subject_url, dest, manifest, opts))
            # Saved per subject (not per file) to keep rewrites of a large
            # manifest cheap; the finally below covers an interruption.
            _write_manifest(dest, manifest)
    finally:
        _write_manifest(dest, manifest)
    return out


def _probe_trials(
    code: str,
    subject_url: str,
    dest: Path,
    manifest: dict[str, dict[str, Any]],
    opts: dict[str, Any],
) -> list[Path]:
    # Probing and downloading are one request: a trial that exists is fetched
    # right away, and complete trials are skipped without asking the server.
    out = []
    for t in range(1, _MAX_TRIALS + 1):
        name = f"{code}_{t:02d}.amc"
        try:
            path, _ = _download_one(subject_url + name, dest, f"{code}/{name}", manifest, **opts)
        except DownloadError as e:
            if e.status == 404:
                break
            raise
        out.append(path)
    return out


def verify_cache(dest: Path | None = None) -> list[str]:
    """Re-check the downloaded files against the manifest's SHA-256 and size.

    Args:
        dest: Download folder; ``default_cache_dir() / "cmu"`` when None.

    Returns:
        Relative paths (as in the manifest, ``/``-separated, sorted) of the files
        that are missing or whose size or checksum no longer matches. A call to
        :func:`download_cmu` fetches them again.

    Raises:
        FileNotFoundError: If ``dest`` has no manifest.
    """
    dest = Path(dest) if dest is not None else default_cache_dir() / "cmu"
    path = dest / MANIFEST_NAME
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no download manifest here")
    manifest = _read_manifest(dest)
    return sorted(rel for rel, entry in manifest.items() if not _is_complete(dest / rel, entry))
