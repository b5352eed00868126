"""Download the CMU Graphics Lab Motion Capture Database (ASF/AMC) into a cache.

:func:`download_cmu` fetches the skeleton (``SS.asf``) and every trial
(``SS_TT.amc``) of the requested subjects from CMU's public layout
(``{base_url}/{SS}/{SS}.asf``, ``{base_url}/{SS}/{SS}_{TT}.amc``) into
``dest/{SS}/``, the same layout the motion library loads. What a finished
download guarantees (docs/data.md, "Downloading CMU", says it at length):

- **Complete.** The size of every file is known before its body is trusted
  (``Content-Length``, a ``Content-Range`` total, else the registry); a body
  that ends short is an error, never a file.
- **Atomic and resumable, never spliced.** Bytes stream into ``name.part``
  beside a sidecar ``name.part.json`` holding the server's validator (a strong
  ``ETag``, else ``Last-Modified``) and the size; a resume sends ``Range`` with
  ``If-Range``, and a ``.part`` without a usable sidecar is discarded. Only a
  complete, checked file gets its final name (the library ignores ``*.part``).
- **Checked against a registry, not against itself.** A file the packaged
  ``humotion_gym/mocap/data/cmu_sha256.txt`` names must match its SHA-256 and
  size, or it is deleted and refused; others are recorded in
  ``dest/manifest.json`` as ``"unverified"``, registry matches as
  ``"verified"`` (:func:`verify_cache` tells them apart).
- **Bounded.** Caps on each file (:data:`DEFAULT_MAX_BYTES`) and on the
  listing, a timeout on every socket read, and deadlines per file and per run.

Each AMC file's manifest entry also records its CMU description, activity
label and person (:mod:`humotion_gym.mocap.cmu`). Every :class:`DownloadError`
names the URL and says what was left on disk. Only the standard library speaks
HTTP; tqdm draws the progress bars. To re-record the registry::

    python -m humotion_gym.mocap.download --record-registry ../shared/mocap/cmu-asfamc
"""

from __future__ import annotations

import argparse
import contextlib
import http.client
import json
import os
import re
import sys
import time
import urllib.error
import urllib.request
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from tqdm.auto import tqdm

from humotion_gym.checks import is_count, is_integer
from humotion_gym.files import write_text_atomically
from humotion_gym.mocap._http import (
    _MAX_TRIALS,
    DownloadError,
    _Deadline,
    _open,
    _Part,
    _read_listing,
    _stream,
    failure_words,
)
from humotion_gym.mocap._registry import (
    REGISTRY_PATH,
    RegistryEntry,
    _check_file,
    _resolve_registry,
    _sha256,
    load_registry,
    record_registry,
)
from humotion_gym.mocap.cmu import (
    cmu_description,
    cmu_label,
    cmu_person,
    subjects_by_activity,
)
from humotion_gym.mocap.library import default_cache_dir

__all__ = [
    "CMU_BASE_URL",
    "DEFAULT_FILE_DEADLINE_S",
    "DEFAULT_MAX_BYTES",
    "DEFAULT_MAX_LISTING_BYTES",
    "DEFAULT_MAX_LISTING_ENTRIES",
    "DEFAULT_RUN_DEADLINE_S",
    "DEFAULT_TIMEOUT_S",
    "MANIFEST_NAME",
    "REGISTRY_PATH",
    "CacheReport",
    "DownloadError",
    "RegistryEntry",
    "choose_cmu_subjects",
    "cmu_download_dir",
    "cmu_subject_code",
    "default_cache_dir",
    "download_cmu",
    "list_cmu_trials",
    "load_registry",
    "record_registry",
    "verify_cache",
]

#: Where CMU serves its subjects' ASF/AMC files.
CMU_BASE_URL = "http://mocap.cs.cmu.edu/subjects"
#: The manifest of finished files, at the top of the download folder.
MANIFEST_NAME = "manifest.json"

#: Cap on one file's size by suffix, in bytes. CMU's skeletons are about 7 KB and
#: its longest trials a few MB, so these leave ample room while refusing junk.
#: Raise with ``max_bytes=`` or ``--max-asf-mib`` / ``--max-amc-mib``.
DEFAULT_MAX_BYTES: Mapping[str, int] = {".asf": 1 << 20, ".amc": 64 << 20, ".bvh": 64 << 20}
#: Cap on a file whose suffix :data:`DEFAULT_MAX_BYTES` does not name.
FALLBACK_MAX_BYTES = 64 << 20
#: Cap on the size of a subject's HTML listing (CMU's are a few KB).
DEFAULT_MAX_LISTING_BYTES = 1 << 20
#: Cap on the number of trials one listing may name (trial numbers run 1..999).
DEFAULT_MAX_LISTING_ENTRIES = 999
#: Socket timeout in seconds, for the connection and for every single read.
DEFAULT_TIMEOUT_S = 30.0
#: Deadline for one file (all its attempts together) and for one listing, seconds.
DEFAULT_FILE_DEADLINE_S = 600.0
#: Deadline for a whole :func:`download_cmu` call, seconds.
DEFAULT_RUN_DEADLINE_S = 7200.0
#: Seconds to wait before the first retry; doubles with each retry (capped at 8 s)
#: so a briefly overloaded server is not hammered. Tests set it to 0.
RETRY_BACKOFF_S = 1.0

# Statuses worth another attempt; any other HTTP error is final (a 403 or 410
# will not change by asking again).
_RETRY_STATUSES = frozenset({408, 425, 429, 500, 502, 503, 504})


@dataclass(frozen=True)
class CacheReport:
    """What :func:`verify_cache` found, by relative path (``/``-separated, sorted).

    Attributes:
        verified: Files whose SHA-256 matches the registry.
        unverified: Files the registry does not name, intact against the manifest
            (complete, but checked only against their own download).
        corrupt: Files whose size or SHA-256 disagrees with the registry or the
            manifest; never counted as verified.
        missing: Files in the manifest that are no longer on disk.
        reasons: For each corrupt or missing file, why.
        absent: Subjects asked for of which neither the manifest nor the
            folder holds a file.
    """

    verified: list[str] = field(default_factory=list)
    unverified: list[str] = field(default_factory=list)
    corrupt: list[str] = field(default_factory=list)
    missing: list[str] = field(default_factory=list)
    reasons: dict[str, str] = field(default_factory=dict)
    absent: list[int] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        """True when nothing is corrupt or missing and every subject asked for is there."""
        return not self.corrupt and not self.missing and not self.absent

    def summary(self) -> str:
        """One line of counts, then one line per corrupt or missing file and why."""
        lines = [
            f"{len(self.verified)} verified (match the registry), "
            f"{len(self.unverified)} unverified (not in the registry; size and manifest "
            f"checked), {len(self.corrupt)} corrupt, {len(self.missing)} missing"
        ]
        lines += [f"  subject {s}: nothing of it downloaded here" for s in self.absent]
        return "\n".join(lines + [f"  {self.reasons[rel]}" for rel in self.problems])

    @property
    def problems(self) -> list[str]:
        """Corrupt and missing files together, sorted; :func:`download_cmu` refetches them."""
        return sorted(self.corrupt + self.missing)


def cmu_download_dir(dest: str | Path | None = None) -> Path:
    """Where CMU's files are downloaded: ``dest``, else ``default_cache_dir() / "cmu"``."""
    return Path(dest) if dest is not None else default_cache_dir() / "cmu"


def cmu_subject_code(subject: int) -> str:
    """The CMU folder name of a subject: two digits, three from subject 100 on.

    Raises:
        TypeError: If ``subject`` is not an integer.
        ValueError: If ``subject`` is outside 1..999.
    """
    if not is_integer(subject):  # True as "subject 1" is almost surely a bug
        raise TypeError(f"subjects: expected integers, got {subject!r}")
    n = int(subject)
    if not 1 <= n <= 999:
        raise ValueError(f"subjects: CMU subject numbers are 1..999, got {n}")
    return f"{n:02d}"


def _subject_url(base_url: str, code: str) -> str:
    return f"{base_url.rstrip('/')}/{code}/"


def list_cmu_trials(
    subject: int,
    base_url: str = CMU_BASE_URL,
    timeout: float = DEFAULT_TIMEOUT_S,
    *,
    max_listing_bytes: int = DEFAULT_MAX_LISTING_BYTES,
    max_listing_entries: int = DEFAULT_MAX_LISTING_ENTRIES,
    deadline_s: float = DEFAULT_FILE_DEADLINE_S,
) -> list[int]:
    """The trial numbers of a subject, read from the folder's HTML listing.

    Args:
        subject: CMU subject number (1..999).
        base_url: Where the subject folders are.
        timeout: Socket timeout in seconds, per connect and per read.
        max_listing_bytes: Cap on the listing's size.
        max_listing_entries: Cap on the number of trials it may name.
        deadline_s: Seconds the whole listing may take.

    Returns:
        Sorted trial numbers, or an empty list when the listing cannot be had or
        names no trial (the caller then probes trial numbers instead).

    Raises:
        DownloadError: If the listing is over a cap or its deadline passes.
    """
    code = cmu_subject_code(subject)
    deadline = _Deadline(
        time.monotonic() + deadline_s, f"the listing's deadline of {deadline_s:g} s"
    )
    url = _subject_url(base_url, code)
    return _read_listing(url, code, timeout, deadline, max_listing_bytes, max_listing_entries)


def _read_manifest(dest: Path, strict: bool = False) -> dict[str, dict[str, Any]]:
    """The download folder's manifest; ``{}`` where it is missing or damaged.

    The manifest is written atomically, so damage came from outside: a download
    takes it as empty (every file is fetched and verified again). ``strict``
    (:func:`verify_cache`, which checks what the manifest records) refuses it.

    Raises:
        OSError: With ``strict``, if the manifest cannot be read.
        ValueError: With ``strict``, if the manifest is not a JSON object.
    """
    path = dest / MANIFEST_NAME
    if not path.is_file():
        return {}
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except ValueError:  # JSON's and UTF-8's errors
        data = None
    except OSError:  # unreadable: a download refetches; a check says why
        if strict:
            raise
        data = None
    if isinstance(data, dict):
        return data
    if strict:
        raise ValueError(
            f"{path}: damaged download manifest (expected a JSON object); "
            "`humotion-gym download cmu` checks and records every file again"
        )
    return {}


def _write_manifest(dest: Path, manifest: dict[str, dict[str, Any]]) -> None:
    text = json.dumps(manifest, indent=1, sort_keys=True) + "\n"
    write_text_atomically(dest / MANIFEST_NAME, text)


def _fetch(
    part: _Part,
    *,
    retries: int,
    timeout: float,
    deadline: _Deadline,
    max_bytes: int,
    expected: RegistryEntry | None,
    progress: bool,
) -> tuple[int, str]:
    """Download ``part.url`` into ``part.path``, checked; return (size, sha256).

    On return ``part.path`` holds the complete file, its size matching the
    server's and, for a registered file, its SHA-256 the registry's.

    Raises:
        DownloadError: On a final HTTP error, a refusal (over the cap, no size,
            registry mismatch), the deadline, or when ``retries`` attempts failed.
    """
    url = part.url
    failures = 0
    restarted = False
    last = ""
    with tqdm(
        desc=part.target.name,
        unit="B",
        unit_scale=True,
        unit_divisor=1024,
        leave=False,
        disable=not progress,
    ) as bar:
        while True:
            if deadline.left() <= 0:
                raise part.give_up(f"stopped at {deadline.what} ({last or 'no answer'})")
            have, validator, total = part.resume_point()
            headers = {"Range": f"bytes={have}-", "If-Range": validator} if have else {}
            try:
                with _open(url, timeout, deadline, headers) as resp:
                    _stream(
                        resp,
                        part,
                        have,
                        total,
                        bar,
                        timeout=timeout,
                        deadline=deadline,
                        max_bytes=max_bytes,
                        expected=expected,
                    )
                break
            except urllib.error.HTTPError as e:
                e.close()
                if e.code in (412, 416) and have and not restarted:
                    # 412: the server refused our precondition; 416: our .part is
                    # at or past the end of its file. Either way the file is not
                    # the one the .part began: start over from zero, once.
                    part.discard()
                    restarted = True
                    continue
                if e.code not in _RETRY_STATUSES:
                    raise part.give_up(f"HTTP {e.code} {e.reason}", status=e.code) from e
                last = f"HTTP {e.code} {e.reason}"
            except (OSError, http.client.HTTPException) as e:
                # URLError, timeouts, resets, IncompleteRead and our _Retry all
                # mean "try again from where we are".
                last = failure_words(e, url)
            failures += 1
            if deadline.left() <= 0:
                raise part.give_up(f"stopped at {deadline.what} ({last})")
            if failures >= retries:
                raise part.give_up(
                    f"failed after {failures} attempt{'s' * (failures != 1)} "
                    f"({part.size()} bytes received): {last}"
                )
            time.sleep(max(min(RETRY_BACKOFF_S * 2 ** (failures - 1), 8.0, deadline.left()), 0))
    size = part.size()
    sha = _sha256(part.path)
    if expected is not None and sha != expected.sha256:
        raise part.give_up(
            f"refused {part.target}: its SHA-256 {sha} disagrees with the registry's "
            f"{expected.sha256} (deleted)",
            keep=False,
        )
    return size, sha


def _resolve_caps(max_bytes: int | Mapping[str, int] | None) -> dict[str, int]:
    """Suffix -> cap in bytes; the key ``""`` holds the cap of other suffixes."""
    caps = {**DEFAULT_MAX_BYTES, "": FALLBACK_MAX_BYTES}
    if isinstance(max_bytes, Mapping):
        caps.update({k.lower(): v for k, v in max_bytes.items()})
    elif max_bytes is not None:
        caps = dict.fromkeys(caps, max_bytes)
    for suffix, cap in caps.items():
        if not is_count(cap, 1):
            raise ValueError(f"max_bytes: caps must be positive integers, got {suffix!r}: {cap!r}")
    return caps


def _download_one(
    url: str,
    dest: Path,
    rel: str,
    manifest: dict[str, dict[str, Any]],
    *,
    registry: Mapping[str, RegistryEntry],
    caps: Mapping[str, int],
    file_deadline_s: float,
    run_deadline: _Deadline,
    retries: int,
    timeout: float,
    progress: bool,
) -> Path:
    """Fetch one file unless the manifest (and registry) say it is intact; its path."""
    target = dest / rel
    expected = registry.get(rel)
    if _check_file(target, manifest.get(rel), expected) is None:
        return target
    target.parent.mkdir(parents=True, exist_ok=True)
    # Drop the stale entry and any unverified file at the final name first: if
    # the download then fails, no final-named file is left that the manifest
    # does not vouch for (the library would load it as a clip).
    manifest.pop(rel, None)
    target.unlink(missing_ok=True)
    part = _Part(url, target)
    size, sha = _fetch(
        part,
        retries=retries,
        timeout=timeout,
        deadline=_file_deadline(file_deadline_s, run_deadline),
        max_bytes=caps.get(target.suffix.lower(), caps[""]),
        expected=expected,
        progress=progress,
    )
    os.replace(part.path, target)
    part.sidecar.unlink(missing_ok=True)
    manifest[rel] = {
        "sha256": sha,
        "bytes": size,
        "url": url,
        "status": "verified" if expected is not None else "unverified",
        "downloaded_at": datetime.now(timezone.utc).isoformat(timespec="seconds"),
    }
    return target


def download_cmu(
    subjects: Sequence[int],
    dest: Path | None = None,
    base_url: str = CMU_BASE_URL,
    progress: bool = True,
    retries: int = 3,
    timeout: float = DEFAULT_TIMEOUT_S,
    *,
    max_bytes: int | Mapping[str, int] | None = None,
    max_listing_bytes: int = DEFAULT_MAX_LISTING_BYTES,
    max_listing_entries: int = DEFAULT_MAX_LISTING_ENTRIES,
    file_deadline_s: float = DEFAULT_FILE_DEADLINE_S,
    deadline_s: float = DEFAULT_RUN_DEADLINE_S,
    registry: Mapping[str, RegistryEntry] | str | Path | None = None,
) -> list[Path]:
    """Download the ASF skeleton and every AMC trial of CMU subjects, checked.

    Files land in ``dest/{SS}/`` (``SS`` the two- or three-digit subject
    number), the layout :func:`humotion_gym.mocap.library.load_library` reads.
    A subject's trials come from the HTML listing of ``{base_url}/{SS}/``; when
    there is none, trial numbers 1, 2, 3... are tried until the first 404.
    Files already intact (in the manifest with matching size and SHA-256, and
    matching the registry where it names them) are not fetched again;
    resumable ``.part`` files of earlier calls are resumed (see the module's
    docstring for what a finished file guarantees).

    Args:
        subjects: CMU subject numbers (1..999); duplicates are fetched once.
        dest: Download folder; ``default_cache_dir() / "cmu"`` when None.
        base_url: Where the subject folders are served.
        progress: Show a tqdm bar (bytes) per file; silent when False.
        retries: Attempts per file before giving up (at least 1).
        timeout: Socket timeout in seconds, per connect and per read.
        max_bytes: Cap on one file's size in bytes: one number for every file,
            or suffix -> cap (``{".amc": 128 << 20}``) over
            :data:`DEFAULT_MAX_BYTES`; the defaults when None.
        max_listing_bytes: Cap on a subject's HTML listing, bytes.
        max_listing_entries: Cap on the trials one listing may name.
        file_deadline_s: Seconds one file (all its attempts) or listing may take.
        deadline_s: Seconds the whole call may take.
        registry: Expected SHA-256 and sizes: a mapping, a registry file, or
            None for the packaged one (:data:`REGISTRY_PATH`). ``{}`` checks no
            file against a registry (all are recorded as unverified).

    Returns:
        The paths of all the subjects' files, skipped ones included: per
        subject the ASF, then the AMC files by trial number.

    Raises:
        ValueError: If a subject number is outside 1..999, or ``retries``, a
            cap or a deadline is not positive.
        TypeError: If a subject number is not an integer.
        DownloadError: If a subject does not exist (its ASF gives HTTP 404), a
            file is refused (over its cap, no size known, registry mismatch), a
            deadline passes, a listing is over its caps, or a file still fails
            after ``retries`` attempts.

    Example:
        >>> paths = download_cmu([2], progress=False)  # doctest: +SKIP
    """
    if isinstance(subjects, int):
        subjects = [subjects]  # a lone subject number is an easy slip to forgive
    # Validate everything before the first request so a typo fails fast.
    codes = list(dict.fromkeys(cmu_subject_code(s) for s in subjects))
    _check_positive(
        retries=retries, timeout=timeout, file_deadline_s=file_deadline_s,
        deadline_s=deadline_s, max_listing_bytes=max_listing_bytes,
        max_listing_entries=max_listing_entries,
    )  # fmt: skip
    caps = _resolve_caps(max_bytes)
    reg = _resolve_registry(registry)
    run_deadline = _Deadline(
        time.monotonic() + deadline_s,
        f"the run's deadline of {deadline_s:g} s (deadline_s=, --deadline)",
    )
    dest = cmu_download_dir(dest)
    # what was there before, so that a failed run leaves no empty folder or
    # empty manifest of its own (its error says nothing is kept)
    before = {p for p in (dest, dest / MANIFEST_NAME, *(dest / c for c in codes)) if p.exists()}
    dest.mkdir(parents=True, exist_ok=True)
    manifest = _read_manifest(dest)
    opts: dict[str, Any] = {
        "registry": reg, "caps": caps, "file_deadline_s": file_deadline_s,
        "run_deadline": run_deadline, "retries": retries, "timeout": timeout,
        "progress": progress,
    }  # fmt: skip
    out: list[Path] = []
    try:
        for code in codes:
            out += _download_subject(
                code, base_url, dest, manifest, opts, max_listing_bytes, max_listing_entries
            )
            _label_entries(manifest, code)
            # Saved per subject (not per file) to keep rewrites of a large
            # manifest cheap; the finally below covers an interruption.
            _write_manifest(dest, manifest)
    finally:
        _leave(dest, manifest, codes, before)
    return out


def _leave(dest: Path, manifest: dict, codes: Sequence[str], before: set[Path]) -> None:
    """Save the manifest if it holds anything or was there; remove folders made and left empty."""
    if manifest or dest / MANIFEST_NAME in before:
        _write_manifest(dest, manifest)
    for folder in [*(dest / c for c in codes), dest]:
        if folder not in before and folder.is_dir() and not any(folder.iterdir()):
            with contextlib.suppress(OSError):  # another process's file came in: kept
                folder.rmdir()


def _check_positive(**values: float) -> None:
    """Refuse an argument of :func:`download_cmu` that is not positive (``retries`` < 1)."""
    for name, value in values.items():
        if name == "retries" and value < 1:
            raise ValueError(f"retries: need at least 1 attempt, got {value}")
        if not value > 0:  # NaN too
            raise ValueError(f"{name}: must be positive, got {value!r}")


def _download_subject(
    code: str,
    base_url: str,
    dest: Path,
    manifest: dict[str, dict[str, Any]],
    opts: dict[str, Any],
    max_listing_bytes: int,
    max_listing_entries: int,
) -> list[Path]:
    """One subject's skeleton and trials (from its listing, else probed) into ``dest``.

    Raises:
        DownloadError: As :func:`download_cmu` documents (a missing subject is a 404).
    """
    timeout, file_deadline_s = opts["timeout"], opts["file_deadline_s"]
    run_deadline: _Deadline = opts["run_deadline"]
    out: list[Path] = []
    subject_url = _subject_url(base_url, code)
    try:
        path = _download_one(
            subject_url + f"{code}.asf", dest, f"{code}/{code}.asf", manifest, **opts
        )
    except DownloadError as e:
        if e.status == 404:
            raise DownloadError(
                e.url, f"CMU subject {int(code)} not found (HTTP 404)", status=404
            ) from None
        raise
    out.append(path)
    listing_deadline = _file_deadline(file_deadline_s, run_deadline)
    trials = _read_listing(
        subject_url, code, timeout, listing_deadline, max_listing_bytes, max_listing_entries
    )
    # Without a listing, trial numbers are probed: probing and downloading are
    # one request, so a trial that exists is fetched right away, complete
    # trials are skipped without asking the server, and the first 404 ends it.
    for t in trials or range(1, _MAX_TRIALS + 1):
        name = f"{code}_{t:02d}.amc"
        try:
            path = _download_one(subject_url + name, dest, f"{code}/{name}", manifest, **opts)
        except DownloadError as e:
            if e.status == 404 and not trials:
                break
            raise
        out.append(path)
    return out


def _file_deadline(file_deadline_s: float, run_deadline: _Deadline) -> _Deadline:
    """The deadline of one file or listing: its own, unless the run's comes first."""
    if file_deadline_s < run_deadline.left():
        return _Deadline(
            time.monotonic() + file_deadline_s,
            f"the per-file deadline of {file_deadline_s:g} s (file_deadline_s=, --file-deadline)",
        )
    return run_deadline


def _label_entries(manifest: dict[str, dict[str, Any]], code: str) -> None:
    """Add CMU's description, the activity label and the person to a subject's AMC entries."""
    for rel, entry in manifest.items():
        m = re.fullmatch(rf"{code}/{code}_(\d+)\.amc", rel)
        if m:
            subject, trial = int(code), int(m[1])
            entry["description"] = cmu_description(subject, trial)
            entry["label"] = cmu_label(subject, trial)
            entry["person"] = cmu_person(subject)


def choose_cmu_subjects(
    activities: Sequence[str], persons: int | None = None, include_test: bool = True
) -> list[int]:
    """CMU subjects to download for some activities, from the packaged index.

    Args:
        activities: Activity labels (``["walk"]``, ``["run", "jump"]``...).
        persons: How many distinct persons (all who did it when None).
        include_test: Also choose test persons
            (:data:`humotion_gym.mocap.cmu.CMU_TEST_PERSONS`); False picks
            training persons only.

    Returns:
        Subject numbers, most trials of the activities first, one per person.

    Raises:
        ValueError: If an activity is not a known label or ``persons`` < 1.
    """
    return subjects_by_activity(activities, persons, exclude_test=not include_test)


def verify_cache(
    dest: Path | None = None,
    registry: Mapping[str, RegistryEntry] | str | Path | None = None,
    subjects: Sequence[int] | None = None,
) -> CacheReport:
    """Re-check the downloaded files against the registry and the manifest.

    A file the registry names is verified only if its SHA-256 and size match
    the registry, whatever the manifest says; a file it does not name is
    unverified if it still matches the manifest's record of its download.

    Args:
        dest: Download folder; ``default_cache_dir() / "cmu"`` when None.
        registry: As for :func:`download_cmu`; the packaged one when None.
        subjects: Check only these subjects' files (None: every file); a
            subject with none is ``absent`` in the report.

    Returns:
        A :class:`CacheReport`: verified, unverified, corrupt and missing files.
        A call to :func:`download_cmu` fetches the corrupt and missing ones again.

    A motion file on disk that the manifest does not record (an interrupted
    or foreign file) is corrupt: :func:`download_cmu` fetches it again.

    Raises:
        FileNotFoundError: If ``dest`` has no manifest.
        ValueError: If the manifest is not a JSON object (damaged outside the
            package, which writes it atomically): nothing it records can be
            checked; :func:`download_cmu` records every file again.
    """
    dest = cmu_download_dir(dest)
    path = dest / MANIFEST_NAME
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no download manifest here")
    manifest = _read_manifest(dest, strict=True)
    reg = _resolve_registry(registry)
    on_disk = {
        p.relative_to(dest).as_posix() for p in dest.glob("*/*") if p.suffix in (".asf", ".amc")
    }
    absent = []
    if subjects is not None:
        folders = {cmu_subject_code(s): s for s in subjects}
        manifest = {rel: e for rel, e in manifest.items() if rel.split("/")[0] in folders}
        on_disk = {rel for rel in on_disk if rel.split("/")[0] in folders}
        seen = {rel.split("/")[0] for rel in [*manifest, *on_disk]}
        absent = [s for code, s in folders.items() if code not in seen]
    report = CacheReport(absent=absent)
    for rel in sorted(on_disk - set(manifest)):
        report.corrupt.append(rel)
        report.reasons[rel] = f"{dest / rel}: not in the manifest"
    for rel, entry in sorted(manifest.items()):
        expected = reg.get(rel)
        why = _check_file(dest / rel, entry, expected)
        if why == "missing":
            report.missing.append(rel)
            report.reasons[rel] = f"{dest / rel}: missing"
        elif why is not None:
            report.corrupt.append(rel)
            report.reasons[rel] = f"{dest / rel}: {why}"
        elif expected is not None:
            report.verified.append(rel)
        else:
            report.unverified.append(rel)
    report.corrupt.sort()
    return report


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m humotion_gym.mocap.download``: record or check the registry.

    ``--record-registry DIR [--out FILE]`` records SHA-256 and sizes of CMU's
    original files under ``DIR`` (the packaged registry when no ``--out``);
    ``--verify DEST`` prints a :class:`CacheReport` of a download folder.
    """
    parser = argparse.ArgumentParser(
        prog="python -m humotion_gym.mocap.download", description=main.__doc__
    )
    group = parser.add_mutually_exclusive_group(required=True)
    group.add_argument("--record-registry", type=Path, metavar="DIR")
    group.add_argument("--verify", type=Path, metavar="DEST")
    parser.add_argument("--out", type=Path, default=None, help="registry file to write")
    args = parser.parse_args(argv)
    try:
        if args.record_registry is not None:
            entries = record_registry(args.record_registry, args.out)
            print(f"{len(entries)} entries in {args.out or REGISTRY_PATH}")
            return 0
        report = verify_cache(args.verify)
    except (ValueError, FileNotFoundError) as exc:
        print(f"{parser.prog}: error: {exc}", file=sys.stderr)
        return 2
    print(report.summary())
    return 0 if report.ok else 1


if __name__ == "__main__":
    sys.exit(main())
