"""Tests of the CMU downloader against local HTTP servers on 127.0.0.1 only.

Every server here is an ``http.server`` in a thread of this process, bound to
127.0.0.1 on a free port, shut down by its fixture; clients use timeouts of a
few seconds and misbehaving handlers stop by themselves (``MAX_HANDLER_S``).
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import random
import re
import threading
import time
from email.utils import formatdate
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import pytest

from baselines import cli
from humotion_gym.mocap import download as dl
from humotion_gym.mocap._http import _trials_from_listing, _validator
from humotion_gym.mocap.download import (
    MANIFEST_NAME,
    REGISTRY_PATH,
    DownloadError,
    RegistryEntry,
    cmu_subject_code,
    download_cmu,
    list_cmu_trials,
    load_registry,
    record_registry,
    verify_cache,
)

SHARED_CMU = Path(__file__).resolve().parents[3] / "shared" / "mocap" / "cmu-asfamc"
needs_shared = pytest.mark.skipif(
    not (SHARED_CMU / "02" / "02.asf").is_file(),
    reason=f"shared CMU mirror not found at {SHARED_CMU}",
)

# Short enough that a stuck test fails in seconds, long enough for a loaded CI box.
TIMEOUT = 5.0
# No misbehaving handler (a slow drip) runs longer than this.
MAX_HANDLER_S = 10.0


class MirrorServer(ThreadingHTTPServer):
    """A file server with Range/If-Range support and switches for misbehaviour."""

    daemon_threads = True  # a handler stuck in a test must not block teardown

    def __init__(self, root: Path) -> None:
        super().__init__(("127.0.0.1", 0), functools.partial(MirrorHandler, directory=str(root)))
        self.root = root
        self.requests: list[tuple[str, str | None]] = []  # (path, Range)
        self.if_ranges: list[tuple[str, str | None]] = []  # (path, If-Range)
        self.listing = True  # serve directory listings
        self.listing_body: bytes | None = None  # serve this as every listing instead
        self.listing_length = True  # send Content-Length with listing_body
        self.honour_range = True
        self.star_total = False  # Content-Range: bytes a-b/* (the file's size not said)
        self.validators: str | None = "etag"  # "etag", "last-modified", "fixed" or None
        self.if_range_412 = False  # answer 412 to any request with If-Range
        self.cuts: dict[str, int] = {}  # URL path -> how many more times to cut (-1: always)
        self.cut_at: dict[str, int] = {}  # URL path -> send this many bytes of the body, once
        self.range_shift: dict[str, int] = {}  # URL path -> a 206 this far past the start, once
        self.drip_ends: dict[str, str] = {}  # URL path -> how its drip ended
        self.drip_ended = threading.Event()
        self.stall_s: dict[str, float] = {}  # URL path -> sleep this long mid-body, once
        self.no_length: set[str] = set()  # URL paths served without Content-Length
        self.drip_s: dict[str, float] = {}  # URL path -> send one byte per this many seconds
        self.header_drip_s: dict[str, float] = {}  # URL path -> headers at one byte per ... s
        self.status: dict[str, int] = {}  # URL path -> answer with this HTTP error
        self.stopping = threading.Event()
        self.lock = threading.Lock()

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.server_address[1]}"

    def file_requests(self) -> list[tuple[str, str | None]]:
        return [r for r in self.requests if not r[0].endswith("/")]

    def _take(self, table: dict, path: str):
        with self.lock:
            if path not in table:
                return None
            value = table[path]
            if isinstance(value, int) and value > 0:
                table[path] = value - 1
                if table[path] == 0:
                    del table[path]
            elif not isinstance(value, int):
                del table[path]
            return value

    def _pop(self, table: dict, path: str):
        """``table[path]`` (None if absent), used once."""
        with self.lock:
            return table.pop(path, None)


class MirrorHandler(SimpleHTTPRequestHandler):
    server: MirrorServer
    protocol_version = "HTTP/1.1"

    def log_message(self, *args) -> None:  # keep the test output clean
        pass

    def _validator_headers(self, path: Path, data: bytes) -> dict[str, str]:
        mode = self.server.validators
        if mode == "etag":
            return {"ETag": '"' + hashlib.sha256(data).hexdigest()[:16] + '"'}
        if mode == "last-modified":
            return {"Last-Modified": formatdate(path.stat().st_mtime, usegmt=True)}
        if mode == "fixed":  # a server whose validator never changes (a lying one)
            return {"ETag": '"fixed"'}
        return {}

    def do_GET(self) -> None:
        srv = self.server
        rng = self.headers.get("Range")
        if_range = self.headers.get("If-Range")
        with srv.lock:
            srv.requests.append((self.path, rng))
            srv.if_ranges.append((self.path, if_range))
        if self.path in srv.status:
            self.send_error(srv.status[self.path])
            return
        if self.path in srv.header_drip_s:
            self.wfile.write(b"HTTP/1.1 200 OK\r\nX-Slow: ")
            self._drip(b"a" * 60000, srv.header_drip_s[self.path])
            return
        path = Path(self.translate_path(self.path))
        if path.is_dir():
            if srv.listing_body is not None:
                self.send_response(200)
                self.send_header("Content-Type", "text/html; charset=utf-8")
                if srv.listing_length:
                    self.send_header("Content-Length", str(len(srv.listing_body)))
                else:
                    self.send_header("Connection", "close")
                    self.close_connection = True
                self.end_headers()
                with _quiet_disconnect():
                    self.wfile.write(srv.listing_body)
                return
            if not srv.listing:
                self.send_error(404)
                return
            super().do_GET()
            return
        if not path.is_file():
            self.send_error(404)
            return
        data = path.read_bytes()
        validators = self._validator_headers(path, data)
        start = 0
        partial = False
        if rng and srv.honour_range:
            if if_range is not None and srv.if_range_412:
                self.send_response(412)
                self.send_header("Content-Length", "0")
                self.end_headers()
                return
            # If-Range: the range only if the validator still matches, else the whole file.
            if if_range is None or if_range in validators.values():
                start = int(re.fullmatch(r"bytes=(\d+)-", rng)[1])
                start += srv._pop(srv.range_shift, self.path) or 0  # a range not asked for
                partial = True
        if partial and start >= len(data):
            self.send_response(416)
            self.send_header("Content-Range", f"bytes */{len(data)}")
            self.send_header("Content-Length", "0")
            self.end_headers()
            return
        body = data[start:]
        self.send_response(206 if partial else 200)
        if partial:
            total = "*" if srv.star_total else len(data)
            self.send_header("Content-Range", f"bytes {start}-{len(data) - 1}/{total}")
        for k, v in validators.items():
            self.send_header(k, v)
        self.send_header("Content-Type", "application/octet-stream")
        if self.path in srv.no_length:
            # The body ends when the connection closes: a cut looks like the end.
            self.send_header("Connection", "close")
            self.close_connection = True
        else:
            self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        drip = srv.drip_s.get(self.path)
        if drip is not None:
            self._drip(body, drip)
            return
        cut_at = srv._pop(srv.cut_at, self.path)
        if cut_at is not None:
            with _quiet_disconnect():
                self.wfile.write(body[:cut_at])
                self.wfile.flush()
            self.close_connection = True
            return
        stall = srv._take(srv.stall_s, self.path)
        if srv._take(srv.cuts, self.path) is not None or stall is not None:
            # Half the body sent, then the socket closes (or stalls past the
            # client's timeout).
            with _quiet_disconnect():
                self.wfile.write(body[: len(body) // 2])
                self.wfile.flush()
            if stall is not None:
                time.sleep(stall)
            self.close_connection = True
            return
        with _quiet_disconnect():
            self.wfile.write(body)

    def _drip(self, body: bytes, every_s: float) -> None:
        t0 = time.monotonic()
        self.close_connection = True
        end = "the client hung up"  # unless the loop ends otherwise
        with _quiet_disconnect():
            for i in range(len(body)):
                if self.server.stopping.is_set() or time.monotonic() - t0 > MAX_HANDLER_S:
                    end = "the server stopped it"
                    break
                self.wfile.write(body[i : i + 1])
                self.wfile.flush()
                time.sleep(every_s)
            else:
                end = "all sent"
        self.server.drip_ends[self.path] = end
        self.server.drip_ended.set()


class _quiet_disconnect:
    """Ignore the client hanging up (what a refused or stopped download does)."""

    def __enter__(self) -> None:
        return None

    def __exit__(self, kind, value, tb) -> bool:
        return kind is not None and issubclass(kind, (BrokenPipeError, ConnectionResetError))


def serve(root: Path):
    srv = MirrorServer(root)
    thread = threading.Thread(target=srv.serve_forever, kwargs={"poll_interval": 0.05})
    thread.daemon = True
    thread.start()
    return srv, thread


def stop(srv: MirrorServer, thread: threading.Thread) -> None:
    srv.stopping.set()
    srv.shutdown()
    srv.server_close()
    thread.join(timeout=5)


@pytest.fixture(autouse=True)
def _no_proxy_no_backoff(monkeypatch):
    # A proxy from the environment would swallow requests to 127.0.0.1.
    for var in ("http_proxy", "HTTP_PROXY", "all_proxy", "ALL_PROXY"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setattr(dl, "RETRY_BACKOFF_S", 0.0)


def make_mirror(root: Path) -> dict[str, bytes]:
    """Subject 1 with three trials and subject 7 with two, random bytes."""
    rng = random.Random(0)
    files = {
        "01/01.asf": 3000,
        "01/01_01.amc": 20000,
        "01/01_02.amc": 15001,
        "01/01_03.amc": 7,
        "07/07.asf": 2500,
        "07/07_01.amc": 9000,
        "07/07_02.amc": 12000,
    }
    out = {}
    for rel, n in files.items():
        data = rng.randbytes(n)
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_bytes(data)
        out[rel] = data
    return out


def registry_of(files: dict[str, bytes], *rels: str) -> dict[str, RegistryEntry]:
    return {r: RegistryEntry(hashlib.sha256(files[r]).hexdigest(), len(files[r])) for r in rels}


@pytest.fixture
def tiny(tmp_path):
    root = tmp_path / "mirror"
    files = make_mirror(root)
    srv, thread = serve(root)
    try:
        yield srv, files, tmp_path / "dest"
    finally:
        stop(srv, thread)


@pytest.fixture
def shared_server():
    srv, thread = serve(SHARED_CMU)
    try:
        yield srv
    finally:
        stop(srv, thread)


def get(srv, dest, subjects=(1,), **kw):
    kw.setdefault("progress", False)
    kw.setdefault("timeout", TIMEOUT)
    # The random mirror reuses CMU's names: check it against no registry unless told.
    kw.setdefault("registry", {})
    return download_cmu(subjects, dest, base_url=srv.url, **kw)


def _all_but(srv, dest, rel: str) -> None:
    """Download subject 7, then drop ``rel``: a later run fetches ``rel`` alone.

    So that a deadline test times the slow file only, never a quick one that a
    busy machine happened to hold up past a deadline of half a second.
    """
    get(srv, dest, subjects=[7])
    (dest / rel).unlink()


def final_files(dest: Path) -> set[str]:
    return {
        p.relative_to(dest).as_posix()
        for p in dest.rglob("*")
        if p.is_file() and p.name != MANIFEST_NAME and not p.name.endswith((".part", ".part.json"))
    }


def leftovers(dest: Path) -> set[str]:
    """Partial downloads and sidecars left on disk."""
    return {p.relative_to(dest).as_posix() for p in dest.rglob("*.part*")}


def manifest_of(dest: Path) -> dict:
    return json.loads((dest / MANIFEST_NAME).read_text())


# --- argument checks (no network) ---------------------------------------------


def test_subject_codes():
    assert cmu_subject_code(2) == "02"
    assert cmu_subject_code(35) == "35"
    assert cmu_subject_code(143) == "143"


@pytest.mark.parametrize("bad", [0, -3, 1000])
def test_subject_out_of_range_names_the_argument(bad, tmp_path):
    with pytest.raises(ValueError, match=rf"subjects.*{bad}"):
        download_cmu([2, bad], tmp_path, base_url="http://127.0.0.1:9", progress=False)
    assert not (tmp_path / MANIFEST_NAME).exists()  # failed before any request


def test_non_integer_subject_rejected(tmp_path):
    with pytest.raises(TypeError, match="subjects"):
        download_cmu(["2"], tmp_path, base_url="http://127.0.0.1:9", progress=False)


@pytest.mark.parametrize(
    "kw",
    [{"deadline_s": 0}, {"file_deadline_s": -1}, {"max_bytes": 0}, {"max_bytes": {".amc": -5}}],
)
def test_bad_caps_and_deadlines_rejected(kw, tmp_path):
    with pytest.raises(ValueError, match=next(iter(kw))):
        download_cmu([2], tmp_path, base_url="http://127.0.0.1:9", progress=False, **kw)


def test_listing_parser_accepts_apache_and_http_server_hrefs():
    html = (
        '<a href="02_01.amc">02_01.amc</a> <A HREF="/subjects/02/02_10.amc">x</a>'
        " <a href=02_03.amc>y</a> <a href='02_01.amc'>dup</a> <a href=\"02_04.amc.part\">no</a>"
        ' <a href="12_02.amc">other subject</a> <a href="02.asf">asf</a>'
    )
    assert _trials_from_listing(html, "02") == [1, 3, 10]


# --- tiny mirror built here: the normal path ----------------------------------


def test_full_download_is_byte_identical_with_manifest(tiny):
    srv, files, dest = tiny
    paths = get(srv, dest, subjects=[1, 7, 1])  # duplicate fetched once
    rels = [p.relative_to(dest).as_posix() for p in paths]
    assert rels == list(files)  # ASF first, then trials in order; subject order kept
    assert final_files(dest) == set(files)
    assert leftovers(dest) == set()
    manifest = manifest_of(dest)
    assert set(manifest) == set(files)
    for rel, data in files.items():
        assert (dest / rel).read_bytes() == data
        entry = manifest[rel]
        assert entry["sha256"] == hashlib.sha256(data).hexdigest()
        assert entry["bytes"] == len(data)
        assert entry["url"] == f"{srv.url}/{rel}"
        assert entry["status"] == "unverified"  # no registry names these
        assert "T" in entry["downloaded_at"]
    report = verify_cache(dest, registry={})
    assert report.ok and report.unverified == sorted(files) and report.verified == []


def test_second_call_skips_complete_files(tiny):
    srv, files, dest = tiny
    get(srv, dest, subjects=[1, 7])
    assert len(srv.file_requests()) == len(files)
    srv.requests.clear()
    paths = get(srv, dest, subjects=[1, 7])
    assert len(paths) == len(files)
    assert srv.file_requests() == []  # only the two listings were asked for
    assert len(srv.requests) == 2


def test_cut_connection_resumes_with_range_and_if_range(tiny):
    srv, files, dest = tiny
    rel = "01/01_02.amc"
    srv.cuts[f"/{rel}"] = 1
    get(srv, dest)
    tries = [r for r in srv.requests if r[0] == f"/{rel}"]
    half = len(files[rel]) // 2
    assert tries == [(f"/{rel}", None), (f"/{rel}", f"bytes={half}-")]
    etag = '"' + hashlib.sha256(files[rel]).hexdigest()[:16] + '"'
    assert (f"/{rel}", etag) in srv.if_ranges
    assert (dest / rel).read_bytes() == files[rel]
    assert verify_cache(dest, registry={}).ok


def test_later_call_resumes_left_part_file(tiny):
    srv, files, dest = tiny
    rel = "01/01_01.amc"
    srv.cuts[f"/{rel}"] = 1
    with pytest.raises(DownloadError, match=rf"{re.escape(srv.url)}/{rel}.*10000 bytes") as err:
        get(srv, dest, retries=1)
    part = dest / (rel + ".part")
    assert err.value.path == part and str(part) in str(err.value)  # names what is on disk
    assert not (dest / rel).exists()
    assert part.stat().st_size == len(files[rel]) // 2
    assert json.loads((dest / (rel + ".part.json")).read_text())["total"] == len(files[rel])
    # The ASF finished before the failure and is recorded.
    assert "01/01.asf" in manifest_of(dest)
    srv.requests.clear()
    get(srv, dest)
    assert (f"/{rel}", "bytes=10000-") in srv.requests
    assert ("/01/01.asf", None) not in srv.requests
    assert (dest / rel).read_bytes() == files[rel]
    assert leftovers(dest) == set()


def test_server_that_always_cuts_leaves_no_final_file(tiny):
    srv, files, dest = tiny
    rel = "01/01_01.amc"
    srv.cuts[f"/{rel}"] = -1
    with pytest.raises(DownloadError) as err:
        get(srv, dest, retries=3)
    assert err.value.url == f"{srv.url}/{rel}"
    assert "3 attempts" in str(err.value) and "bytes received" in str(err.value)
    assert 0 < err.value.received < len(files[rel])
    assert len([r for r in srv.requests if r[0] == f"/{rel}"]) == 3  # bounded
    assert not (dest / rel).exists()
    assert rel not in manifest_of(dest)
    assert rel not in final_files(dest)


def test_server_ignoring_range_restarts_from_zero(tiny):
    srv, files, dest = tiny
    srv.honour_range = False
    rel = "01/01_01.amc"
    srv.cuts[f"/{rel}"] = 1
    get(srv, dest)
    tries = [r for r in srv.requests if r[0] == f"/{rel}"]
    assert tries[1][1] == f"bytes={len(files[rel]) // 2}-"  # asked for a range, got 200
    assert (dest / rel).read_bytes() == files[rel]


def test_server_without_validators_is_not_resumed(tiny):
    # Without ETag or Last-Modified a resume could not be checked: start over.
    srv, files, dest = tiny
    srv.validators = None
    rel = "01/01_01.amc"
    srv.cuts[f"/{rel}"] = 1
    with pytest.raises(DownloadError, match="nothing kept on disk") as err:
        get(srv, dest, retries=1)
    assert err.value.path is None and leftovers(dest) == set()
    get(srv, dest)
    assert [r for r in srv.requests if r[0] == f"/{rel}"][-1] == (f"/{rel}", None)
    assert (dest / rel).read_bytes() == files[rel]


def test_stalled_server_times_out_and_resumes(tiny):
    srv, files, dest = tiny
    rel = "07/07_01.amc"
    _all_but(srv, dest, rel)
    srv.stall_s[f"/{rel}"] = 1.5
    get(srv, dest, subjects=[7], timeout=0.3)
    assert (f"/{rel}", f"bytes={len(files[rel]) // 2}-") in srv.requests
    assert (dest / rel).read_bytes() == files[rel]


def test_missing_subject_is_a_clear_error(tiny):
    srv, _, dest = tiny
    with pytest.raises(DownloadError, match=rf"{re.escape(srv.url)}/05/05\.asf.*subject 5") as e:
        get(srv, dest, subjects=[5])
    assert isinstance(e.value, ValueError) and e.value.status == 404
    assert len(srv.requests) == 1  # a 404 is not retried


def test_no_listing_probes_trials(tiny):
    srv, files, dest = tiny
    srv.listing = False
    paths = get(srv, dest, subjects=[1])
    assert [p.name for p in paths] == ["01.asf", "01_01.amc", "01_02.amc", "01_03.amc"]
    assert ("/01/01_04.amc", None) in srv.requests  # the 404 that ended the probe
    assert final_files(dest) == {r for r in files if r.startswith("01/")}
    srv.requests.clear()
    get(srv, dest, subjects=[1])  # complete trials are not probed again
    assert [r[0] for r in srv.file_requests()] == ["/01/01_04.amc"]


def test_list_trials_without_listing_is_empty(tiny):
    srv, _, _ = tiny
    assert list_cmu_trials(7, srv.url, TIMEOUT) == [1, 2]
    srv.listing = False
    assert list_cmu_trials(7, srv.url, TIMEOUT) == []


def test_verify_cache_detects_corruption_and_download_repairs(tiny):
    srv, files, dest = tiny
    get(srv, dest, subjects=[1, 7])
    rel = "07/07_02.amc"
    data = bytearray((dest / rel).read_bytes())
    data[100] ^= 0xFF  # same size, different content
    (dest / rel).write_bytes(bytes(data))
    (dest / "01" / "01_03.amc").unlink()
    report = verify_cache(dest, registry={})
    assert report.corrupt == [rel] and report.missing == ["01/01_03.amc"]
    assert report.problems == ["01/01_03.amc", rel] and not report.ok
    assert "manifest says" in report.reasons[rel]
    srv.requests.clear()
    get(srv, dest, subjects=[1, 7])
    assert sorted(r[0] for r in srv.file_requests()) == ["/01/01_03.amc", f"/{rel}"]
    assert verify_cache(dest, registry={}).ok
    assert (dest / rel).read_bytes() == files[rel]


def test_failed_repair_leaves_no_damaged_final_file(tiny):
    srv, files, dest = tiny
    get(srv, dest, subjects=[7])
    rel = "07/07_01.amc"
    (dest / rel).write_bytes(b"damaged")
    srv.cuts[f"/{rel}"] = -1
    with pytest.raises(DownloadError, match="07_01.amc"):
        get(srv, dest, subjects=[7], retries=2)
    assert not (dest / rel).exists()
    assert rel not in manifest_of(dest)
    assert (dest / "07" / "07.asf").read_bytes() == files["07/07.asf"]  # untouched


@pytest.mark.parametrize("damage", ["{}", "{bad", "null", "", "[1]", "\xff"])
def test_verify_cache_never_passes_a_damaged_manifest(tiny, damage):
    srv, _, dest = tiny
    get(srv, dest, subjects=[7])
    manifest = dest / "manifest.json"
    if damage == "{}":  # readable, but records none of the files on disk
        manifest.write_text(damage)
        report = verify_cache(dest, registry={})
        assert not report.ok and report.verified == report.unverified == []
        assert report.corrupt == sorted(report.corrupt) and "07/07_01.amc" in report.corrupt
        assert report.reasons["07/07_01.amc"].endswith("not in the manifest")
        srv.requests.clear()
        get(srv, dest, subjects=[7])  # the download records them again
        assert verify_cache(dest, registry={}).ok
        return
    manifest.write_bytes(damage.encode("latin-1"))
    with pytest.raises(ValueError, match="manifest.json: damaged download manifest"):
        verify_cache(dest, registry={})


def test_verify_cache_without_manifest(tmp_path):
    with pytest.raises(FileNotFoundError, match="manifest"):
        verify_cache(tmp_path)


def test_default_dest_honours_env(tiny, monkeypatch):
    srv, files, dest = tiny
    monkeypatch.setenv("HUMOTION_CACHE", str(dest / "cache"))
    paths = download_cmu([7], base_url=srv.url, progress=False, timeout=TIMEOUT)
    assert paths[0] == dest / "cache" / "cmu" / "07" / "07.asf"
    assert (dest / "cache" / "cmu" / MANIFEST_NAME).is_file()


def test_progress_silent_when_disabled(tiny, capsys):
    srv, _, dest = tiny
    get(srv, dest, subjects=[7], progress=False)
    assert capsys.readouterr() == ("", "")
    get(srv, dest / "again", subjects=[7], progress=True)
    assert "07_02.amc" in capsys.readouterr().err


# --- faults found by the fault-injection campaign -----------------------------


def test_cut_without_content_length_is_refused(tiny):
    # Fault: a body cut with no Content-Length was accepted as complete.
    srv, files, dest = tiny
    rel = "07/07_01.amc"
    srv.no_length.add(f"/{rel}")
    srv.cuts[f"/{rel}"] = -1
    with pytest.raises(DownloadError, match="no Content-Length.*nothing kept on disk") as err:
        get(srv, dest, subjects=[7])
    assert err.value.url == f"{srv.url}/{rel}" and err.value.path is None
    assert rel not in final_files(dest) and leftovers(dest) == set()
    assert rel not in manifest_of(dest)
    assert len([r for r in srv.requests if r[0] == f"/{rel}"]) == 1  # refusal is final


def test_cut_without_content_length_fails_the_cli(tiny, capsys):
    srv, _, dest = tiny
    srv.no_length.add("/07/07_02.amc")
    srv.cuts["/07/07_02.amc"] = -1
    argv = ["download", "cmu", "--subjects", "7", "--dest", str(dest), "--quiet"]
    rc = cli.main([*argv, "--base-url", srv.url, "--timeout", str(TIMEOUT)])
    assert rc != 0
    err = capsys.readouterr().err
    assert f"{srv.url}/07/07_02.amc" in err and "no Content-Length" in err
    assert not (dest / "07" / "07_02.amc").exists()


def test_no_content_length_checked_against_registry_size(tiny):
    # With no Content-Length the registry's size tells a cut from the end.
    srv, files, dest = tiny
    rel = "07/07_01.amc"
    srv.no_length.add(f"/{rel}")
    srv.cuts[f"/{rel}"] = 1
    get(srv, dest, subjects=[7], registry=registry_of(files, rel))
    half = len(files[rel]) // 2
    assert [r for r in srv.requests if r[0] == f"/{rel}"][1] == (f"/{rel}", f"bytes={half}-")
    assert (dest / rel).read_bytes() == files[rel]
    assert manifest_of(dest)[rel]["status"] == "verified"


@pytest.mark.parametrize("validators", ["etag", "last-modified"])
def test_file_changed_on_server_is_restarted_not_spliced(tiny, validators):
    # Fault: a resume spliced a stale .part with a file that changed on the server.
    srv, files, dest = tiny
    srv.validators = validators
    rel = "01/01_01.amc"
    srv.cuts[f"/{rel}"] = 1
    with pytest.raises(DownloadError, match=r"kept in .*01_01\.amc\.part"):
        get(srv, dest, retries=1)
    side = json.loads((dest / (rel + ".part.json")).read_text())
    new = random.Random(1).randbytes(len(files[rel]))  # same size, other content
    mirror = srv.root / rel
    mirror.write_bytes(new)
    later = mirror.stat().st_mtime + 100
    os.utime(mirror, (later, later))
    srv.requests.clear()
    srv.if_ranges.clear()
    get(srv, dest)
    half = len(new) // 2
    assert srv.if_ranges[[r[0] for r in srv.requests].index(f"/{rel}")] == (
        f"/{rel}",
        side["validator"],
    )
    assert (f"/{rel}", f"bytes={half}-") in srv.requests  # asked to resume, got 200
    assert (dest / rel).read_bytes() == new  # the new file, whole
    assert (dest / rel).read_bytes() != files[rel][:half] + new[half:]
    assert manifest_of(dest)[rel]["sha256"] == hashlib.sha256(new).hexdigest()
    assert leftovers(dest) == set()


def test_412_on_resume_restarts_from_zero(tiny):
    srv, files, dest = tiny
    rel = "01/01_02.amc"
    srv.cuts[f"/{rel}"] = 1
    srv.if_range_412 = True
    get(srv, dest)
    tries = [r for r in srv.requests if r[0] == f"/{rel}"]
    half = len(files[rel]) // 2
    assert tries == [(f"/{rel}", None), (f"/{rel}", f"bytes={half}-"), (f"/{rel}", None)]
    assert (dest / rel).read_bytes() == files[rel]


def test_server_ignoring_if_range_with_other_size_is_not_spliced(tiny):
    # A server whose validator never changes answers 206 for a file of another size.
    srv, files, dest = tiny
    srv.validators = "fixed"
    rel = "01/01_01.amc"
    srv.cuts[f"/{rel}"] = 1
    with pytest.raises(DownloadError):
        get(srv, dest, retries=1)
    new = random.Random(2).randbytes(len(files[rel]) + 500)
    (srv.root / rel).write_bytes(new)
    get(srv, dest)
    assert (dest / rel).read_bytes() == new


@pytest.mark.parametrize("sidecar", [None, "other-url", "no-validator", "past-its-total"])
def test_stale_part_is_discarded_not_spliced(tiny, sidecar):
    srv, files, dest = tiny
    rel = "01/01_01.amc"
    part = dest / (rel + ".part")
    part.parent.mkdir(parents=True)
    part.write_bytes(b"stale bytes of some other download" * 10)
    url = f"{srv.url}/{rel}"
    side = {"url": url, "validator": '"x"', "total": len(files[rel])}
    if sidecar == "other-url":
        side["url"] = url + "?old"
    elif sidecar == "no-validator":
        side["validator"] = None
    elif sidecar == "past-its-total":  # one byte longer than the file it says it began
        side["total"] = part.stat().st_size - 1
    if sidecar is not None:
        (dest / (rel + ".part.json")).write_text(json.dumps(side))
    get(srv, dest)
    assert [r for r in srv.requests if r[0] == f"/{rel}"] == [(f"/{rel}", None)]
    assert (dest / rel).read_bytes() == files[rel]
    assert leftovers(dest) == set()


def test_stale_part_longer_than_file_is_restarted(tiny):
    srv, files, dest = tiny
    srv.validators = "fixed"
    rel = "01/01_03.amc"  # 7 bytes on the server
    (dest / "01").mkdir(parents=True)
    (dest / (rel + ".part")).write_bytes(b"x" * 100)
    side = {"url": f"{srv.url}/{rel}", "validator": '"fixed"', "total": 200}
    (dest / (rel + ".part.json")).write_text(json.dumps(side))
    get(srv, dest)  # 416, then from zero
    tries = [r for r in srv.requests if r[0] == f"/{rel}"]
    assert tries == [(f"/{rel}", "bytes=100-"), (f"/{rel}", None)]
    assert (dest / rel).read_bytes() == files[rel]


def test_body_one_byte_short_is_resumed_not_kept(tiny):
    srv, files, dest = tiny
    rel = "01/01_02.amc"
    n = len(files[rel])
    srv.cut_at[f"/{rel}"] = n - 1  # Content-Length says n; the connection closes at n - 1
    get(srv, dest)
    tries = [r for r in srv.requests if r[0] == f"/{rel}"]
    assert tries == [(f"/{rel}", None), (f"/{rel}", f"bytes={n - 1}-")]
    assert (dest / rel).read_bytes() == files[rel]
    assert manifest_of(dest)[rel]["bytes"] == n


def test_a_range_of_unsaid_total_is_resumed_by_its_length(tiny):
    # bytes a-b/*: the .part's bytes and the Content-Length make the file's size.
    srv, files, dest = tiny
    srv.star_total = True
    rel = "01/01_02.amc"
    half = len(files[rel]) // 2
    srv.cuts[f"/{rel}"] = 1
    get(srv, dest)
    tries = [r for r in srv.requests if r[0] == f"/{rel}"]
    assert tries == [(f"/{rel}", None), (f"/{rel}", f"bytes={half}-")]
    assert (dest / rel).read_bytes() == files[rel]


def test_a_range_not_asked_for_is_restarted_not_appended(tiny):
    # A 206 whose Content-Range starts elsewhere than the .part ends: appending would splice.
    srv, files, dest = tiny
    rel = "01/01_02.amc"
    half = len(files[rel]) // 2
    srv.cuts[f"/{rel}"] = 1
    srv.range_shift[f"/{rel}"] = 100  # bytes half+100- sent, and said so, for bytes=half-
    get(srv, dest)
    tries = [r for r in srv.requests if r[0] == f"/{rel}"]
    assert tries == [(f"/{rel}", None), (f"/{rel}", f"bytes={half}-"), (f"/{rel}", None)]
    assert (dest / rel).read_bytes() == files[rel]
    assert leftovers(dest) == set()


def test_a_weak_etag_is_no_if_range_validator():
    # If-Range allows strong validators only: a weak ETag gives way to Last-Modified.
    when = "Wed, 21 Oct 2015 07:28:00 GMT"
    assert _validator({"ETag": ' "abc" ', "Last-Modified": when}) == '"abc"'
    assert _validator({"ETag": 'W/"abc"', "Last-Modified": when}) == when
    assert _validator({"ETag": 'W/"abc"'}) is None
    assert _validator({}) is None


def test_oversize_file_refused(tiny):
    # Fault: no size cap (64 MiB of junk accepted).
    srv, files, dest = tiny
    rel = "01/01_01.amc"  # 20000 bytes
    with pytest.raises(DownloadError, match=r"20000 bytes is over the cap of 10000.*max-amc-mib"):
        get(srv, dest, max_bytes={".amc": 10000})
    assert len([r for r in srv.requests if r[0] == f"/{rel}"]) == 1  # refused, not retried
    assert rel not in final_files(dest) and leftovers(dest) == set()
    assert rel not in manifest_of(dest)


def test_oversize_asf_refused_by_default_cap(tiny):
    srv, files, dest = tiny
    (srv.root / "07" / "07.asf").write_bytes(b"#" * ((1 << 20) + 1))
    with pytest.raises(DownloadError, match=r"07\.asf.*over the cap of 1048576 bytes"):
        get(srv, dest, subjects=[7])
    assert final_files(dest) == set() and leftovers(dest) == set()


def test_oversize_cap_raised_from_cli(tiny, capsys):
    srv, _, dest = tiny
    argv = ["download", "cmu", "--subjects", "7", "--dest", str(dest), "--quiet"]
    argv += ["--base-url", srv.url, "--timeout", str(TIMEOUT)]
    assert cli.main([*argv, "--max-asf-mib", "0.001"]) != 0  # 1048 bytes < 2500
    assert "over the cap of 1048 bytes" in capsys.readouterr().err
    assert cli.main([*argv, "--max-asf-mib", "1"]) == 0
    assert (dest / "07" / "07.asf").is_file()


def test_body_without_length_longer_than_registry_refused(tiny):
    srv, files, dest = tiny
    rel = "07/07_01.amc"
    srv.no_length.add(f"/{rel}")
    reg = {rel: RegistryEntry(hashlib.sha256(files[rel]).hexdigest(), 100)}
    with pytest.raises(DownloadError, match=r"more than the 100 bytes expected"):
        get(srv, dest, subjects=[7], registry=reg)
    assert rel not in final_files(dest) and leftovers(dest) == set()


def test_slow_drip_stopped_at_file_deadline(tiny):
    # Fault: no deadline (a 1 byte/s server kept the download running for hours).
    srv, files, dest = tiny
    rel = "07/07_01.amc"
    _all_but(srv, dest, rel)
    srv.drip_s[f"/{rel}"] = 0.05
    with pytest.raises(DownloadError, match=r"per-file deadline of 0\.5 s") as err:
        get(srv, dest, subjects=[7], file_deadline_s=0.5)
    assert err.value.url == f"{srv.url}/{rel}"
    # What arrived is kept, resumable, and the message names it.
    assert err.value.path == dest / (rel + ".part") and err.value.path.is_file()
    assert 0 < err.value.path.stat().st_size < len(files[rel])
    assert rel not in final_files(dest)


def test_slow_drip_stopped_at_run_deadline(tiny):
    srv, files, dest = tiny
    _all_but(srv, dest, "07/07_02.amc")
    srv.drip_s["/07/07_02.amc"] = 0.05
    with pytest.raises(DownloadError, match=r"07_02\.amc.*run's deadline of 0\.5 s"):
        get(srv, dest, subjects=[7], deadline_s=0.5)
    assert "07/07_02.amc" not in final_files(dest)


def test_headers_dripped_stopped_at_deadline(tiny):
    # A server can drag out its headers too; the deadline's watchdog stops it.
    srv, _, dest = tiny
    rel = "07/07_01.amc"
    _all_but(srv, dest, rel)
    srv.header_drip_s[f"/{rel}"] = 0.05
    with pytest.raises(DownloadError, match=r"07_01\.amc: stopped at the per-file deadline"):
        get(srv, dest, subjects=[7], file_deadline_s=0.5)
    assert rel not in final_files(dest) and leftovers(dest) == set()
    # The deadline's watchdog cut the connection: the server did not end it for the client.
    assert srv.drip_ended.wait(MAX_HANDLER_S + 5)
    assert srv.drip_ends == {f"/{rel}": "the client hung up"}


def test_stall_near_deadline_ends_at_deadline(tiny):
    # A stall shorter than the read timeout but past the deadline stops at the deadline.
    srv, _, dest = tiny
    _all_but(srv, dest, "07/07_01.amc")
    srv.stall_s["/07/07_01.amc"] = 3.0
    with pytest.raises(DownloadError, match="deadline"):
        get(srv, dest, subjects=[7], file_deadline_s=0.5, timeout=TIMEOUT)


@pytest.mark.parametrize("with_length", [True, False])
def test_huge_listing_refused(tiny, with_length):
    # Fault: the listing was not capped.
    srv, _, dest = tiny
    srv.listing_body = b"<html>" + b"x" * (2 << 20)
    srv.listing_length = with_length
    with pytest.raises(DownloadError, match=r"/07/: listing .*over the cap of 1048576 bytes"):
        get(srv, dest, subjects=[7])
    with pytest.raises(DownloadError, match="over the cap of 1000 bytes"):
        list_cmu_trials(7, srv.url, TIMEOUT, max_listing_bytes=1000)


def test_listing_with_too_many_entries_refused(tiny):
    srv, _, dest = tiny
    rows = "".join(f'<a href="07_{t:02d}.amc">x</a>\n' for t in range(1, 5001))
    srv.listing_body = rows.encode()
    with pytest.raises(DownloadError, match=r"names 5000 trials, over the cap of 999"):
        get(srv, dest, subjects=[7])
    assert list_cmu_trials(7, srv.url, TIMEOUT, max_listing_entries=5000)[-1] == 999


def test_http_500_message_is_truthful(tiny):
    # Fault: after HTTP 500 the message named a .part that did not exist.
    srv, _, dest = tiny
    rel = "07/07_01.amc"
    srv.status[f"/{rel}"] = 500
    with pytest.raises(DownloadError) as err:
        get(srv, dest, subjects=[7], retries=2)
    msg = str(err.value)
    assert msg.startswith(f"{srv.url}/{rel}: ") and "HTTP 500" in msg
    assert "nothing kept on disk" in msg and ".part" not in msg
    assert err.value.path is None and leftovers(dest) == set()


def test_http_500_after_cut_names_the_part_on_disk(tiny):
    srv, files, dest = tiny
    rel = "07/07_01.amc"
    srv.cuts[f"/{rel}"] = 1
    with pytest.raises(DownloadError):
        get(srv, dest, subjects=[7], retries=1)
    srv.status[f"/{rel}"] = 500
    with pytest.raises(DownloadError, match="HTTP 500") as err:
        get(srv, dest, subjects=[7], retries=1)
    part = dest / (rel + ".part")
    assert str(part) in str(err.value) and part.stat().st_size == len(files[rel]) // 2


# --- the registry -------------------------------------------------------------


def test_registry_mismatch_is_refused(tiny):
    # Fault: the manifest recorded whatever arrived, so verify_cache vouched for it.
    srv, files, dest = tiny
    rel = "07/07_01.amc"
    wrong = "0" * 64
    reg = {rel: RegistryEntry(wrong, len(files[rel]))}
    with pytest.raises(DownloadError) as err:
        get(srv, dest, subjects=[7], registry=reg)
    msg = str(err.value)
    got = hashlib.sha256(files[rel]).hexdigest()
    assert err.value.url == f"{srv.url}/{rel}"
    assert str(dest / rel) in msg and got in msg and wrong in msg and "deleted" in msg
    assert not (dest / rel).exists() and leftovers(dest) == set()
    assert rel not in manifest_of(dest)
    assert "07/07.asf" in manifest_of(dest)


def test_registry_size_mismatch_refused_before_body(tiny):
    srv, files, dest = tiny
    rel = "07/07.asf"
    reg = {rel: RegistryEntry(hashlib.sha256(files[rel]).hexdigest(), 7262)}
    with pytest.raises(DownloadError, match=r"2500 bytes, the registry says 7262"):
        get(srv, dest, subjects=[7], registry=reg)
    assert leftovers(dest) == set() and final_files(dest) == set()


def test_registry_match_is_verified_and_never_vouched_otherwise(tiny):
    srv, files, dest = tiny
    reg = registry_of(files, *[r for r in files if r.startswith("01/")])
    get(srv, dest, subjects=[1, 7], registry=reg)
    manifest = manifest_of(dest)
    assert {r for r, e in manifest.items() if e["status"] == "verified"} == set(reg)
    report = verify_cache(dest, registry=reg)
    assert report.verified == sorted(reg)
    assert report.unverified == sorted(r for r in files if r.startswith("07/"))
    assert report.ok
    # A file changed on disk with its manifest entry changed to match: the
    # manifest agrees, the registry does not, so it is corrupt, not verified.
    rel = "01/01_02.amc"
    bad = random.Random(3).randbytes(len(files[rel]))
    (dest / rel).write_bytes(bad)
    manifest[rel]["sha256"] = hashlib.sha256(bad).hexdigest()
    (dest / MANIFEST_NAME).write_text(json.dumps(manifest))
    report = verify_cache(dest, registry=reg)
    assert report.corrupt == [rel] and rel not in report.verified
    assert "registry says" in report.reasons[rel]
    # The same file against no registry is only unverified; download repairs it.
    assert rel in verify_cache(dest, registry={}).unverified
    get(srv, dest, subjects=[1], registry=reg)
    assert (dest / rel).read_bytes() == files[rel]
    assert verify_cache(dest, registry=reg).verified == sorted(reg)


def test_registry_file_round_trip_and_errors(tmp_path):
    src = tmp_path / "src"
    files = make_mirror(src)
    (src / "07" / "notes.txt").write_text("ignored")
    out = tmp_path / "reg.txt"
    entries = record_registry(src, out)
    assert entries == registry_of(files, *files)
    assert load_registry(out) == entries
    assert dl.main(["--record-registry", str(src / ".." / "src"), "--out", str(out)]) == 0
    assert load_registry(out) == entries
    out.write_text("not a registry line\n")
    with pytest.raises(ValueError, match=r"reg\.txt:1"):
        load_registry(out)
    with pytest.raises(FileNotFoundError, match="no CMU files"):
        record_registry(tmp_path / "empty-dir-that-does-not-exist", out)


def test_packaged_registry_lists_cmu_subjects_1_to_3():
    reg = load_registry()
    assert REGISTRY_PATH.name == "cmu_sha256.txt"
    assert len(reg) == 18
    assert {r.split("/")[0] for r in reg} == {"01", "02", "03"}
    assert {"01/01.asf", "02/02_10.amc", "03/03_04.amc"} <= set(reg)


@needs_shared
def test_packaged_registry_matches_shared_originals():
    reg = load_registry()
    for rel, entry in reg.items():
        data = (SHARED_CMU / rel).read_bytes()
        assert (hashlib.sha256(data).hexdigest(), len(data)) == (entry.sha256, entry.bytes), rel


# --- the shared CMU mirror ----------------------------------------------------


@needs_shared
def test_shared_subjects_1_and_2_byte_identical_and_verified(shared_server, tmp_path):
    dest = tmp_path / "cmu"
    paths = get(shared_server, dest, subjects=[1, 2], registry=None)  # the packaged registry
    expected = sorted(
        p.relative_to(SHARED_CMU).as_posix()
        for s in ("01", "02")
        for p in (SHARED_CMU / s).iterdir()
        if p.suffix in (".asf", ".amc")
    )
    assert sorted(p.relative_to(dest).as_posix() for p in paths) == expected
    manifest = manifest_of(dest)
    assert sorted(manifest) == expected
    for rel in expected:
        data = (SHARED_CMU / rel).read_bytes()
        assert (dest / rel).read_bytes() == data
        assert manifest[rel]["sha256"] == hashlib.sha256(data).hexdigest()
        assert manifest[rel]["status"] == "verified"
    report = verify_cache(dest)
    assert report.verified == expected and report.unverified == [] and report.ok
    shared_server.requests.clear()
    get(shared_server, dest, subjects=[1, 2], registry=None)
    assert shared_server.file_requests() == []


def test_cli_verify_reports_and_fails_on_corrupt(tiny, tmp_path, capsys):
    srv, files, dest = tiny
    reg_file = tmp_path / "reg.txt"
    record_registry(srv.root, reg_file)
    base = ["download", "cmu", "--dest", str(dest), "--registry", str(reg_file)]
    assert cli.main([*base, "--subjects", "7", "--quiet", "--base-url", srv.url]) == 0
    capsys.readouterr()
    assert cli.main([*base, "--verify"]) == 0
    assert "3 verified" in capsys.readouterr().out
    (dest / "07" / "07_02.amc").write_bytes(b"junk")
    assert cli.main([*base, "--verify"]) == 1
    out = capsys.readouterr().out
    assert "2 verified" in out and "1 corrupt" in out and "07_02.amc" in out


# --- labels, persons and choosing subjects by activity (issue 17) --------------


def test_manifest_records_labels_and_persons_from_the_index(tiny):
    srv, files, dest = tiny
    get(srv, dest, subjects=[1, 7])
    man = manifest_of(dest)
    from humotion_gym.mocap.cmu import cmu_index, cmu_label

    for rel in ("07/07_01.amc", "07/07_02.amc", "01/01_01.amc"):
        subject, trial = (int(x) for x in Path(rel).stem.split("_"))
        entry = man[rel]
        assert entry["description"] == cmu_index().get(subject, trial).description
        assert entry["label"] == cmu_label(subject, trial)
        assert entry["person"] == f"cmu-{subject:02d}"
    assert man["07/07_01.amc"]["label"] == "walk" and man["01/01_01.amc"]["label"] == "jump"
    assert "label" not in man["07/07.asf"]


def test_choose_subjects_by_activity():
    from humotion_gym.mocap.cmu import CMU_TEST_PERSONS, cmu_person

    walkers = dl.choose_cmu_subjects(["walk"], persons=10)
    assert len(walkers) == 10 and len({cmu_person(s) for s in walkers}) == 10
    train = dl.choose_cmu_subjects(["walk"], persons=10, include_test=False)
    assert not {cmu_person(s) for s in train} & set(CMU_TEST_PERSONS)
    assert set(walkers) - set(train) <= {16}  # the one test walker in the top ten
    with pytest.raises(ValueError, match="unknown label"):
        dl.choose_cmu_subjects(["strolling"])


@pytest.fixture
def walk_mirror(tmp_path):
    """A mirror holding the subject that ``--activity walk --persons 1`` chooses."""
    top = dl.choose_cmu_subjects(["walk"], persons=1)[0]
    code = cmu_subject_code(top)
    root = tmp_path / "mirror"
    rng = random.Random(1)
    for name in (f"{code}.asf", f"{code}_01.amc", f"{code}_02.amc"):
        (root / code).mkdir(parents=True, exist_ok=True)
        (root / code / name).write_bytes(rng.randbytes(500))
    srv, thread = serve(root)
    try:
        yield srv, code, tmp_path / "dest"
    finally:
        stop(srv, thread)


def test_cli_downloads_by_activity_and_prints_the_choice(walk_mirror, capsys):
    srv, code, dest = walk_mirror
    argv = ["download", "cmu", "--activity", "walk", "--persons", "1", "--dest", str(dest)]
    rc = cli.main([*argv, "--quiet", "--base-url", srv.url, "--timeout", str(TIMEOUT)])
    assert rc == 0
    out = capsys.readouterr().out
    assert f"cmu-{code}" in out and "1 subjects chosen for walk" in out
    assert final_files(dest) == {f"{code}/{code}.asf", f"{code}/{code}_01.amc",
                                 f"{code}/{code}_02.amc"}  # fmt: skip
    assert manifest_of(dest)[f"{code}/{code}_01.amc"]["label"] == "walk"


def test_cli_activity_cut_connection_resumes(walk_mirror):
    srv, code, dest = walk_mirror
    srv.cuts[f"/{code}/{code}_02.amc"] = 1
    argv = ["download", "cmu", "--activity", "walk", "--persons", "1", "--dest", str(dest)]
    assert cli.main([*argv, "--quiet", "--base-url", srv.url, "--timeout", str(TIMEOUT)]) == 0
    got = [r for r in srv.requests if r[0] == f"/{code}/{code}_02.amc"]
    assert len(got) == 2 and got[1][1] == "bytes=250-"
    assert leftovers(dest) == set()


def test_cli_activity_arguments_are_checked(capsys):
    assert cli.main(["download", "cmu", "--activity", "strolling"]) == 2
    assert "--activity: no label strolling; the labels are walk, run" in capsys.readouterr().err
    assert cli.main(["download", "cmu", "--persons", "3"]) == 2
    assert "give --activity" in capsys.readouterr().err
    assert cli.main(["download", "cmu", "--activity", "run", "--persons", "2", "--dry-run"]) == 0
    assert "2 subjects chosen for run" in capsys.readouterr().out


def test_cli_verify_checks_only_the_subjects_asked_for(tiny, capsys):
    srv, files, dest = tiny
    get(srv, dest, subjects=[1, 7])
    (dest / "01" / "01_03.amc").unlink()
    base = ["download", "cmu", "--dest", str(dest), "--verify"]
    assert cli.main([*base, "--subjects", "7"]) == 0  # subject 1's damage is not 7's
    out = capsys.readouterr().out
    assert "3 unverified" in out and "0 missing" in out
    assert cli.main([*base, "--subjects", "1"]) == 1
    assert "01_03.amc" in capsys.readouterr().out
    assert cli.main([*base, "--subjects", "7", "35"]) == 1  # 35 was never downloaded
    assert "subject 35: nothing of it downloaded here" in capsys.readouterr().out
    report = verify_cache(dest, registry={}, subjects=[7])
    assert report.ok and all(rel.startswith("07/") for rel in report.unverified)


def test_cli_verify_refuses_the_flags_that_choose_a_download(tiny, capsys):
    srv, files, dest = tiny
    get(srv, dest, subjects=[7])
    base = ["download", "cmu", "--dest", str(dest), "--verify"]
    assert cli.main([*base, "--activity", "walk"]) == 2
    assert "drop --activity" in capsys.readouterr().err
    assert cli.main([*base, "--dry-run"]) == 2


def test_a_download_holds_its_folder_while_verify_and_dry_run_only_read(tiny, capsys):
    fcntl = pytest.importorskip("fcntl")
    srv, files, dest = tiny
    base = ["download", "cmu", "--dest", str(dest)]
    assert cli.main([*base, "--subjects", "7", "--quiet", "--base-url", srv.url]) == 0
    fd = os.open(dest, os.O_RDONLY)  # as a second download into it holds it
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        assert cli.main([*base, "--verify"]) in (0, 1)  # reads: runs beside it
        assert cli.main([*base, "--subjects", "7", "--dry-run"]) == 0
        capsys.readouterr()
        assert cli.main([*base, "--subjects", "7", "--quiet", "--base-url", srv.url]) == 2
        assert "--dest: another humotion-gym command is writing into" in capsys.readouterr().err
    finally:
        os.close(fd)


def test_no_network_is_said_in_words_and_leaves_nothing(tmp_path, monkeypatch):
    """Offline: "cannot reach HOST (no network or DNS: ...)", and no empty folder or manifest."""
    import socket
    import urllib.error

    def offline(*args, **kwargs):
        raise urllib.error.URLError(socket.gaierror(-2, "Name or service not known"))

    monkeypatch.setattr(dl, "_open", offline)
    dest = tmp_path / "dl1"
    with pytest.raises(DownloadError) as err:
        download_cmu([2], dest, base_url="http://mocap.example/", retries=1, progress=False)
    message = str(err.value)
    assert "cannot reach mocap.example (no network or DNS: Name or service not known)" in message
    assert "Errno" not in message and message.endswith("nothing kept on disk")
    assert not dest.exists()
    # a folder that was there stays, with what it held, and gets no empty manifest
    dest.mkdir()
    (dest / "02").mkdir()
    with pytest.raises(DownloadError):
        download_cmu([2, 7], dest, base_url="http://mocap.example/", retries=1, progress=False)
    assert sorted(p.name for p in dest.iterdir()) == ["02"]
