"""The transfer layer of :mod:`humotion_gym.mocap.download`: requests, deadlines, resumable parts.

:class:`DownloadError` (re-exported by :mod:`humotion_gym.mocap.download`),
the per-file and per-run deadlines, opening a URL with the socket timeouts
bounded by the deadline, reading a subject's HTML listing, and streaming one
file into a resumable ``.part`` with its sidecar.
"""

from __future__ import annotations

import contextlib
import http.client
import json
import os
import re
import socket
import threading
import time
import urllib.error
import urllib.parse
import urllib.request
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tqdm.auto import tqdm

from humotion_gym.files import write_text_atomically
from humotion_gym.mocap._registry import RegistryEntry

#: Suffix of a file still being downloaded.
PART_SUFFIX = ".part"
#: Suffix of the sidecar beside a ``.part``: the URL, validator and size it belongs to.
SIDECAR_SUFFIX = ".part.json"
_CHUNK = 1 << 16
# Probing stops here even if a server answers every URL (CMU's largest subject
# has well under a hundred trials).
_MAX_TRIALS = 999
_USER_AGENT = "humotion_gym-download/1 (+urllib)"


class DownloadError(ValueError):
    """A file or listing could not be downloaded, or was refused.

    The message starts with the URL and says what is left on disk.

    Attributes:
        url: The URL that failed.
        status: The HTTP status if the server answered with an error, else None.
        received: Bytes of the file held locally (in its ``.part``) when giving up.
        path: The file left on disk for this URL (a resumable ``.part``), or None
            when nothing was kept.
    """

    def __init__(
        self,
        url: str,
        reason: str,
        *,
        status: int | None = None,
        received: int = 0,
        path: Path | None = None,
    ) -> None:
        self.url = url
        self.status = status
        self.received = received
        self.path = path
        super().__init__(f"{url}: {reason}")


class _Retry(OSError):
    """An attempt failed in a way another attempt may mend (a short body...)."""


@dataclass(frozen=True)
class _Deadline:
    at: float  # time.monotonic() value
    what: str  # e.g. "the per-file deadline of 600 s (file_deadline_s=, --file-deadline)"

    def left(self) -> float:
        return self.at - time.monotonic()


def _opener(socks: list[socket.socket]) -> urllib.request.OpenerDirector:
    """A urllib opener that records every socket it connects, for the watchdog."""

    class _Conn(http.client.HTTPConnection):
        def connect(self) -> None:
            super().connect()
            socks.append(self.sock)

    class _SConn(_Conn, http.client.HTTPSConnection):
        """HTTPS, its (TLS) socket recorded by :class:`_Conn`'s ``connect``."""

    class _Handler(urllib.request.HTTPHandler):
        def http_open(self, req: urllib.request.Request) -> Any:
            return self.do_open(_Conn, req)

    class _SHandler(urllib.request.HTTPSHandler):
        def https_open(self, req: urllib.request.Request) -> Any:
            return self.do_open(_SConn, req)

    return urllib.request.build_opener(_Handler, _SHandler)


@contextlib.contextmanager
def _open(
    url: str, timeout: float, deadline: _Deadline, headers: dict[str, str] | None = None
) -> Iterator[Any]:
    """GET ``url``; the response, its sockets shut down if the deadline passes.

    The per-read timeout bounds a stall; the watchdog bounds everything else a
    server can drag out (headers sent a byte at a time, a body that drips).
    """
    req = urllib.request.Request(url, headers={"User-Agent": _USER_AGENT, **(headers or {})})
    socks: list[socket.socket] = []

    def cut() -> None:
        for sock in list(socks):
            with contextlib.suppress(OSError):
                sock.shutdown(socket.SHUT_RDWR)

    watchdog = threading.Timer(max(deadline.left(), 0.0), cut)
    watchdog.daemon = True
    watchdog.start()
    try:
        with _opener(socks).open(req, timeout=max(min(timeout, deadline.left()), 0.01)) as resp:
            yield resp
    finally:
        watchdog.cancel()


def _set_read_timeout(resp: Any, timeout: float, deadline: _Deadline) -> None:
    """Bound the next socket read by the timeout and by the time left to the deadline."""
    sock = getattr(getattr(getattr(resp, "fp", None), "raw", None), "_sock", None)
    if sock is not None:
        sock.settimeout(max(min(timeout, deadline.left()), 0.01))


def _deadline_error(url: str, deadline: _Deadline, state: str) -> DownloadError:
    return DownloadError(url, f"stopped at {deadline.what}; {state}")


def _trials_from_listing(html: str, code: str) -> list[int]:
    # Accept relative ("02_01.amc"), rooted ("/subjects/02/02_01.amc") and
    # absolute hrefs, quoted or not, as Apache and http.server write them.
    pattern = re.compile(
        rf"""href\s*=\s*["']?(?:[^"'\s>]*/)?{code}_(\d+)\.amc(?=["'\s>?#])""", re.IGNORECASE
    )
    return sorted({int(m) for m in pattern.findall(html)})


def _read_listing(
    url: str, code: str, timeout: float, deadline: _Deadline, max_bytes: int, max_entries: int
) -> list[int]:
    try:
        with _open(url, timeout, deadline) as resp:
            if deadline.left() <= 0:
                raise _deadline_error(url, deadline, "the headers came in too slowly")
            length = resp.headers.get("Content-Length")
            if length and length.isdigit() and int(length) > max_bytes:
                raise DownloadError(
                    url,
                    f"listing of {int(length)} bytes is over the cap of {max_bytes} bytes "
                    "(max_listing_bytes=, --max-listing-kib)",
                )
            charset = resp.headers.get_content_charset() or "utf-8"
            body = bytearray()
            while True:
                if deadline.left() <= 0:
                    raise _deadline_error(url, deadline, f"listing read {len(body)} bytes")
                _set_read_timeout(resp, timeout, deadline)
                chunk = resp.read1(_CHUNK)
                if not chunk:
                    break
                body += chunk
                if len(body) > max_bytes:
                    raise DownloadError(
                        url,
                        f"listing is over the cap of {max_bytes} bytes "
                        "(max_listing_bytes=, --max-listing-kib); nothing written",
                    )
    except (OSError, http.client.HTTPException):
        if deadline.left() <= 0:
            raise _deadline_error(url, deadline, "listing not read") from None
        # No listing (404, listings disabled, network trouble): probing follows.
        return []
    trials = _trials_from_listing(body.decode(charset, errors="replace"), code)
    if len(trials) > max_entries:
        raise DownloadError(
            url,
            f"listing names {len(trials)} trials, over the cap of {max_entries} "
            "(max_listing_entries=)",
        )
    return [t for t in trials if 1 <= t <= _MAX_TRIALS]


def _parse_content_range(value: str | None) -> tuple[int, int | None] | None:
    """``bytes START-END/TOTAL`` -> (START, TOTAL or None); None if unparsable."""
    m = re.fullmatch(r"\s*bytes\s+(\d+)-(\d+)/(\d+|\*)\s*", value or "")
    if not m:
        return None
    return int(m[1]), (int(m[3]) if m[3] != "*" else None)


@dataclass
class _Part:
    """A file being downloaded: ``target.part`` and its sidecar ``target.part.json``."""

    url: str
    target: Path

    @property
    def path(self) -> Path:
        return self.target.with_name(self.target.name + PART_SUFFIX)

    @property
    def sidecar(self) -> Path:
        return self.target.with_name(self.target.name + SIDECAR_SUFFIX)

    def size(self) -> int:
        return self.path.stat().st_size if self.path.exists() else 0

    def discard(self) -> None:
        self.path.unlink(missing_ok=True)
        self.sidecar.unlink(missing_ok=True)

    def read_sidecar(self) -> dict[str, Any] | None:
        try:
            data = json.loads(self.sidecar.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return None
        return data if isinstance(data, dict) and data.get("url") == self.url else None

    def write_sidecar(self, validator: str | None, total: int) -> None:
        write_text_atomically(
            self.sidecar, json.dumps({"url": self.url, "validator": validator, "total": total})
        )

    def resume_point(self) -> tuple[int, str | None, int | None]:
        """(bytes to resume from, If-Range validator, file size) or (0, None, None).

        A ``.part`` that cannot be resumed safely (no sidecar, another URL, no
        validator, longer than the file) is deleted here: never spliced.
        """
        have = self.size()
        side = self.read_sidecar() if have else None
        validator = side.get("validator") if side else None
        total = side.get("total") if side else None
        if (
            not (have and isinstance(validator, str) and validator and isinstance(total, int))
            or have > total
        ):
            self.discard()
            return 0, None, None
        return have, validator, total

    def resumable(self) -> bool:
        side = self.read_sidecar()
        return self.size() > 0 and bool(side and side.get("validator"))

    def give_up(
        self, reason: str, *, status: int | None = None, keep: bool = True
    ) -> DownloadError:
        """The error for this file, after keeping a resumable ``.part`` or deleting it.

        The message says truthfully what is on disk afterwards.
        """
        if keep and self.resumable():
            n = self.size()
            where = f"{n} bytes kept in {self.path} for a later call to resume"
            return DownloadError(
                self.url, f"{reason}; {where}", status=status, received=n, path=self.path
            )
        self.discard()
        return DownloadError(self.url, f"{reason}; nothing kept on disk", status=status)


def failure_words(exc: BaseException, url: str) -> str:
    """Why an attempt at ``url`` failed, in words (not ``[Errno -2] ...``).

    A name that does not resolve means no network (or no DNS), the usual case
    offline; a refused connection, that the host is down or blocked.
    """
    reason = getattr(exc, "reason", None) or exc
    host = urllib.parse.urlsplit(url).hostname or url
    if isinstance(reason, socket.gaierror):
        return f"cannot reach {host} (no network or DNS: {reason.strerror or reason})"
    if isinstance(reason, ConnectionRefusedError):
        return f"cannot reach {host} (connection refused)"
    if isinstance(reason, OSError) and reason.strerror:
        return reason.strerror[:1].lower() + reason.strerror[1:]
    return str(reason) or type(reason).__name__


def _validator(headers: Any) -> str | None:
    """The If-Range validator of a response: a strong ETag, else Last-Modified."""
    etag = (headers.get("ETag") or "").strip()
    if etag and not etag.startswith("W/"):  # weak ETags are not allowed in If-Range
        return etag
    return (headers.get("Last-Modified") or "").strip() or None


def _stream(
    resp: Any,
    part: _Part,
    have: int,
    known_total: int | None,
    bar: tqdm,
    *,
    timeout: float,
    deadline: _Deadline,
    max_bytes: int,
    expected: RegistryEntry | None,
) -> None:
    """Write a response body into ``part``, checking size, cap and deadline.

    Raises:
        _Retry: The body ended short, or the server's range cannot be appended
            (another attempt may mend it).
        DownloadError: A final refusal or the deadline.
    """
    if deadline.left() <= 0:
        # The watchdog cut the connection while the headers came in: what was
        # parsed of them is not to be trusted.
        raise part.give_up(f"stopped at {deadline.what} while the headers came in")
    length = resp.headers.get("Content-Length")
    length = int(length) if length and length.strip().isdigit() else None
    if resp.status == 206:
        rng = _parse_content_range(resp.headers.get("Content-Range"))
        total = rng[1] if rng else None
        if total is None and rng and length is not None:
            total = have + length
        if rng is None or rng[0] != have or (total is not None and total != known_total):
            # A range we did not ask for, or of a file of another size (a
            # server that ignored If-Range): appending would splice two files.
            part.discard()
            raise _Retry(f"unexpected Content-Range {resp.headers.get('Content-Range')!r}")
        start, mode = have, "ab"
    else:
        # 200 to a Range + If-Range request: the file changed (or the server
        # ignores ranges), and the body is the whole file: rewrite from zero.
        start, total, mode = 0, length, "wb"
        part.discard()
    if total is None and expected is not None:
        total = expected.bytes
    if total is None:
        raise part.give_up(
            "the server sent no Content-Length and the registry does not know this file, "
            "so a cut body could not be told from a complete one; refused",
            keep=False,
        )
    if expected is not None and total != expected.bytes:
        raise part.give_up(
            f"refused {part.target}: the server's file is {total} bytes, "
            f"the registry says {expected.bytes}",
            keep=False,
        )
    if total > max_bytes:
        raise part.give_up(
            f"refused {part.target}: {total} bytes is over the cap of {max_bytes} bytes "
            "(raise it with max_bytes= or --max-asf-mib / --max-amc-mib)",
            keep=False,
        )
    if mode == "wb":
        part.path.parent.mkdir(parents=True, exist_ok=True)
        part.write_sidecar(_validator(resp.headers), total)
    size = start
    stop = ""
    bar.reset(total=total)
    bar.update(start)
    with part.path.open(mode) as f:
        while True:
            if deadline.left() <= 0:
                stop = "deadline"
                break
            _set_read_timeout(resp, timeout, deadline)
            # read1, not read: read(n) waits for all n bytes, so on a stall the
            # bytes already received would be lost to the timeout instead of
            # being kept for the resume. One byte more than expected is asked
            # for, to catch a body without Content-Length that runs long.
            chunk = resp.read1(min(_CHUNK, total - size + 1))
            if not chunk:
                break
            if size + len(chunk) > total:
                stop = "overlong"
                break
            f.write(chunk)
            size += len(chunk)
            bar.update(len(chunk))
        f.flush()
        # On disk before the rename, so a crash cannot leave a final-named file
        # with missing blocks.
        os.fsync(f.fileno())
    if stop == "deadline":
        raise part.give_up(f"stopped at {deadline.what} after {size} of {total} bytes")
    if stop == "overlong":
        raise part.give_up(
            f"refused {part.target}: the server sent more than the {total} bytes expected",
            keep=False,
        )
    if size < total:
        raise _Retry(f"body ended at {size} of {total} bytes")
