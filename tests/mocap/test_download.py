"""Tests of the CMU downloader against local HTTP servers on 127.0.0.1 only."""

from __future__ import annotations

import functools
import hashlib
import json
import random
import re
import threading
import time
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import pytest

from humotion_gym.mocap import download as dl
from humotion_gym.mocap.download import (
    MANIFEST_NAME,
    DownloadError,
    cmu_subject_code,
    download_cmu,
    list_cmu_trials,
    verify_cache,
)

SHARED_CMU = Path(__file__).resolve().parents[3] / "shared" / "mocap" / "cmu-asfamc"
needs_shared = pytest.mark.skipif(
    not (SHARED_CMU / "02" / "02.asf").is_file(),
    reason=f"shared CMU mirror not found at {SHARED_CMU}",
)

# Short enough that a stuck test fails in seconds, long enough for a loaded CI box.
TIMEOUT = 5.0


class MirrorServer(ThreadingHTTPServer):
    """A file server with Range support and switches for misbehaviour."""

    daemon_threads = True  # a handler stuck in a test must not block teardown

    def __init__(self, root: Path) -> None:
        super().__init__(("127.0.0.1", 0), functools.partial(MirrorHandler, directory=str(root)))
        self.root = root
        self.requests: list[tuple[str, str | None]] = []
        self.listing = True  # serve directory listings
        self.honour_range = True
        self.cuts: dict[str, int] = {}  # URL path -> how many more times to cut (-1: always)
        self.stall_s: dict[str, float] = {}  # URL path -> sleep this long mid-body, once
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


class MirrorHandler(SimpleHTTPRequestHandler):
    server: MirrorServer
    protocol_version = "HTTP/1.1"

    def log_message(self, *args) -> None:  # keep the test output clean
        pass

    def do_GET(self) -> None:
        srv = self.server
        rng = self.headers.get("Range")
        with srv.lock:
            srv.requests.append((self.path, rng))
        path = Path(self.translate_path(self.path))
        if path.is_dir():
            if not srv.listing:
                self.send_error(404)
                return
            super().do_GET()
            return
        if not path.is_file():
            self.send_error(404)
            return
        data = path.read_bytes()
        start = 0
        if rng and srv.honour_range:
            start = int(re.fullmatch(r"bytes=(\d+)-", rng)[1])
            if start >= len(data):
                self.send_response(416)
                self.send_header("Content-Range", f"bytes */{len(data)}")
                self.send_header("Content-Length", "0")
                self.end_headers()
                return
            self.send_response(206)
            self.send_header("Content-Range", f"bytes {start}-{len(data) - 1}/{len(data)}")
        else:
            self.send_response(200)
        body = data[start:]
        self.send_header("Content-Type", "application/octet-stream")
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        stall = srv._take(srv.stall_s, self.path)
        if srv._take(srv.cuts, self.path) is not None or stall is not None:
            # Full Content-Length announced, half the body sent, then the
            # socket closes (or stalls past the client's timeout).
            self.wfile.write(body[: len(body) // 2])
            self.wfile.flush()
            if stall is not None:
                time.sleep(stall)
            self.close_connection = True
            return
        self.wfile.write(body)


def serve(root: Path):
    srv = MirrorServer(root)
    thread = threading.Thread(target=srv.serve_forever, kwargs={"poll_interval": 0.05})
    thread.daemon = True
    thread.start()
    return srv, thread


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


@pytest.fixture
def tiny(tmp_path):
    root = tmp_path / "mirror"
    files = make_mirror(root)
    srv, thread = serve(root)
    yield srv, files, tmp_path / "dest"
    srv.shutdown()
    srv.server_close()
    thread.join(timeout=5)


@pytest.fixture
def shared_server():
    srv, thread = serve(SHARED_CMU)
    yield srv
    srv.shutdown()
    srv.server_close()
    thread.join(timeout=5)


def get(srv, dest, subjects=(1,), **kw):
    kw.setdefault("progress", False)
    kw.setdefault("timeout", TIMEOUT)
    return download_cmu(subjects, dest, base_url=srv.url, **kw)


def final_files(dest: Path) -> set[str]:
    return {
        p.relative_to(dest).as_posix()
        for p in dest.rglob("*")
        if p.is_file() and p.name != MANIFEST_NAME and not p.name.endswith(".part")
    }


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


def test_listing_parser_accepts_apache_and_http_server_hrefs():
    html = (
        '<a href="02_01.amc">02_01.amc</a> <A HREF="/subjects/02/02_10.amc">x</a>'
        " <a href=02_03.amc>y</a> <a href='02_01.amc'>dup</a> <a href=\"02_04.amc.part\">no</a>"
        ' <a href="12_02.amc">other subject</a> <a href="02.asf">asf</a>'
    )
    assert dl._trials_from_listing(html, "02") == [1, 3, 10]


# --- tiny mirror built here ---------------------------------------------------


def test_full_download_is_byte_identical_with_manifest(tiny):
    srv, files, dest = tiny
    paths = get(srv, dest, subjects=[1, 7, 1])  # duplicate fetched once
    rels = [p.relative_to(dest).as_posix() for p in paths]
    assert rels == list(files)  # ASF first, then trials in order; subject order kept
    assert final_files(dest) == set(files)
    assert not list(dest.rglob("*.part"))
    manifest = json.loads((dest / MANIFEST_NAME).read_text())
    assert set(manifest) == set(files)
    for rel, data in files.items():
        assert (dest / rel).read_bytes() == data
        entry = manifest[rel]
        assert entry["sha256"] == hashlib.sha256(data).hexdigest()
        assert entry["bytes"] == len(data)
        assert entry["url"] == f"{srv.url}/{rel}"
        assert "T" in entry["downloaded_at"]
    assert verify_cache(dest) == []


def test_second_call_skips_complete_files(tiny):
    srv, files, dest = tiny
    get(srv, dest, subjects=[1, 7])
    assert len(srv.file_requests()) == len(files)
    srv.requests.clear()
    paths = get(srv, dest, subjects=[1, 7])
    assert len(paths) == len(files)
    assert srv.file_requests() == []  # only the two listings were asked for
    assert len(srv.requests) == 2


def test_cut_connection_resumes_with_range(tiny):
    srv, files, dest = tiny
    rel = "01/01_02.amc"
    srv.cuts[f"/{rel}"] = 1
    get(srv, dest)
    tries = [r for r in srv.requests if r[0] == f"/{rel}"]
    half = len(files[rel]) // 2
    assert tries == [(f"/{rel}", None), (f"/{rel}", f"bytes={half}-")]
    assert (dest / rel).read_bytes() == files[rel]
    assert verify_cache(dest) == []


def test_later_call_resumes_left_part_file(tiny):
    srv, files, dest = tiny
    rel = "01/01_01.amc"
    srv.cuts[f"/{rel}"] = 1
    with pytest.raises(DownloadError, match=rf"{re.escape(srv.url)}/{rel}.*10000 bytes"):
        get(srv, dest, retries=1)
    assert not (dest / rel).exists()
    assert (dest / (rel + ".part")).stat().st_size == len(files[rel]) // 2
    # The ASF finished before the failure and is recorded.
    assert "01/01.asf" in json.loads((dest / MANIFEST_NAME).read_text())
    srv.requests.clear()
    get(srv, dest)
    assert (f"/{rel}", "bytes=10000-") in srv.requests
    assert ("/01/01.asf", None) not in srv.requests
    assert (dest / rel).read_bytes() == files[rel]
    assert not list(dest.rglob("*.part"))


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
    assert rel not in json.loads((dest / MANIFEST_NAME).read_text())
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


def test_stale_part_longer_than_file_is_restarted(tiny):
    srv, files, dest = tiny
    rel = "01/01_03.amc"  # 7 bytes on the server
    (dest / "01").mkdir(parents=True)
    (dest / (rel + ".part")).write_bytes(b"x" * 100)
    get(srv, dest)  # 416, then from zero
    assert (dest / rel).read_bytes() == files[rel]


def test_stalled_server_times_out_and_resumes(tiny):
    srv, files, dest = tiny
    rel = "07/07_01.amc"
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
    assert verify_cache(dest) == ["01/01_03.amc", rel]
    srv.requests.clear()
    get(srv, dest, subjects=[1, 7])
    assert sorted(r[0] for r in srv.file_requests()) == ["/01/01_03.amc", f"/{rel}"]
    assert verify_cache(dest) == []
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
    assert rel not in json.loads((dest / MANIFEST_NAME).read_text())
    assert (dest / "07" / "07.asf").read_bytes() == files["07/07.asf"]  # untouched


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


# --- the shared CMU mirror ----------------------------------------------------


@needs_shared
def test_shared_subjects_1_and_2_byte_identical(shared_server, tmp_path):
    dest = tmp_path / "cmu"
    paths = get(shared_server, dest, subjects=[1, 2])
    expected = sorted(
        p.relative_to(SHARED_CMU).as_posix()
        for s in ("01", "02")
        for p in (SHARED_CMU / s).iterdir()
        if p.suffix in (".asf", ".amc")
    )
    assert sorted(p.relative_to(dest).as_posix() for p in paths) == expected
    manifest = json.loads((dest / MANIFEST_NAME).read_text())
    assert sorted(manifest) == expected
    for rel in expected:
        data = (SHARED_CMU / rel).read_bytes()
        assert (dest / rel).read_bytes() == data
        assert manifest[rel]["sha256"] == hashlib.sha256(data).hexdigest()
    shared_server.requests.clear()
    get(shared_server, dest, subjects=[1, 2])
    assert shared_server.file_requests() == []
