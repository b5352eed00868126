"""Files are written whole or not at all (:mod:`humotion_gym.files`), videos and figures too."""

from __future__ import annotations

import io
import os
from pathlib import Path

import numpy as np
import pytest

from humotion_gym import video
from humotion_gym.files import (
    json_default,
    load_npz,
    read_json,
    write_atomically,
    write_json_gz,
    write_text_atomically,
)


def _cut(after: int, exc: BaseException):
    """A writer that writes ``after`` bytes to its path, then raises ``exc``."""

    def write(tmp: Path) -> None:
        tmp.write_bytes(b"x" * after)
        raise exc

    return write


def test_a_write_lands_whole_and_leaves_nothing_beside_it(tmp_path: Path) -> None:
    target = tmp_path / "new" / "folder" / "a.json"
    write_text_atomically(target, '{"a": 1}\n')
    assert target.read_text(encoding="utf-8") == '{"a": 1}\n'
    assert [p.name for p in target.parent.iterdir()] == ["a.json"]


@pytest.mark.parametrize("exc", [OSError("disk full"), KeyboardInterrupt()], ids=repr)
def test_a_failed_or_interrupted_write_keeps_the_old_file(
    tmp_path: Path, exc: BaseException
) -> None:
    target = tmp_path / "a.bin"
    target.write_bytes(b"old")
    with pytest.raises(type(exc)):
        write_atomically(target, _cut(100, exc))
    assert target.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["a.bin"]
    with pytest.raises(type(exc)):
        write_atomically(tmp_path / "b.bin", _cut(100, exc))
    assert not (tmp_path / "b.bin").exists()


def test_a_write_replaces_the_file_and_a_reader_of_the_old_one_reads_it_whole(
    tmp_path: Path,
) -> None:
    target = tmp_path / "a.bin"
    target.write_bytes(b"old" * 1000)
    with open(target, "rb") as reader:  # opened before the write, read after it
        write_atomically(target, lambda tmp: tmp.write_bytes(b"new"))
        assert reader.read() == b"old" * 1000  # renamed over, not rewritten in place
    assert target.read_bytes() == b"new"


def test_text_is_synced_to_disk_before_the_rename(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    events: list[tuple[str, int]] = []
    real_fsync, real_replace = os.fsync, os.replace

    def fsync(fd: int) -> None:
        events.append(("fsync", os.fstat(fd).st_size))  # the bytes written when synced
        real_fsync(fd)

    def replace(src: Path, dst: Path) -> None:
        events.append(("replace", Path(src).stat().st_size))
        real_replace(src, dst)

    monkeypatch.setattr(os, "fsync", fsync)
    monkeypatch.setattr(os, "replace", replace)
    write_text_atomically(tmp_path / "a.json", '{"é": 1}')
    assert events == [("fsync", 9), ("replace", 9)]  # flushed, synced, then renamed
    assert (tmp_path / "a.json").read_text(encoding="utf-8") == '{"é": 1}'


def test_the_temporary_name_is_hidden_and_keeps_the_suffix_when_asked(tmp_path: Path) -> None:
    seen: list[Path] = []
    for keep in (False, True):
        write_atomically(
            tmp_path / "v.mp4",
            lambda tmp: (seen.append(tmp), tmp.write_bytes(b"")),
            keep_suffix=keep,
        )
    assert [p.parent for p in seen] == [tmp_path, tmp_path]
    assert all(p.name.startswith(".v.mp4.") for p in seen)
    assert [p.suffix for p in seen] == [".tmp", ".mp4"]  # `cache clear` removes `.*.tmp`
    assert seen[0].name != seen[1].name.removesuffix(".mp4")  # unique to the call


@pytest.mark.parametrize("name", ["v.mp4", "v.avi"])
def test_a_video_interrupted_while_written_leaves_none(
    tmp_path: Path, name: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    frames = [np.full((16, 16, 3), 10 * i, np.uint8) for i in range(6)]
    path = tmp_path / name
    video.write_video(path, frames, fps=10)
    whole = path.read_bytes()
    assert len(whole) > 0
    real, calls = video._to_bgr, []

    def interrupted(frame, scale):
        calls.append(1)
        if len(calls) == 4:  # in the middle of the video
            raise KeyboardInterrupt
        return real(frame, scale)

    monkeypatch.setattr(video, "_to_bgr", interrupted)
    with pytest.raises(KeyboardInterrupt):
        video.write_video(path, frames[::-1], fps=10)
    assert path.read_bytes() == whole
    with pytest.raises(KeyboardInterrupt):
        calls.clear()
        video.write_video(tmp_path / "other" / name, frames, fps=10)
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["other", name]


def test_a_png_that_cannot_be_encoded_leaves_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    video.write_png(tmp_path / "a.png", np.zeros((4, 4, 3), np.uint8))
    assert (tmp_path / "a.png").stat().st_size > 0
    with pytest.raises(ValueError, match=r"b\.nosuchformat: write_png writes \.png files"):
        video.write_png(tmp_path / "b.nosuchformat", np.zeros((4, 4, 3), np.uint8))

    def failing(path: str, image: np.ndarray) -> bool:
        Path(path).write_bytes(b"half")
        return False

    monkeypatch.setattr(video.cv2, "imwrite", failing)
    with pytest.raises(OSError, match=r"c\.png: could not write the PNG"):
        video.write_png(tmp_path / "c.png", np.zeros((4, 4, 3), np.uint8))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.png"]


def test_a_long_name_is_written_and_errors_name_the_file_asked_for(tmp_path: Path) -> None:
    for name in ("a" * 240 + ".json", "é" * 120 + ".txt", "中" * 80 + ".txt"):  # <= 255 bytes
        write_text_atomically(tmp_path / name, "{}")
        assert (tmp_path / name).read_text() == "{}"
    assert len(list(tmp_path.iterdir())) == 3

    def refused(tmp: Path) -> None:
        raise PermissionError(13, "Permission denied", str(tmp))

    with pytest.raises(PermissionError) as caught:
        write_atomically(tmp_path / "b.json", refused)
    assert caught.value.filename == str(tmp_path / "b.json")


def test_a_json_document_round_trips_gzipped_to_the_same_bytes(tmp_path: Path) -> None:
    doc = {"a": np.float64(0.1), "b": np.arange(3), "c": tmp_path, "d": [1.5, None]}
    first, second = tmp_path / "one.json.gz", tmp_path / "two.json.gz"
    write_json_gz(first, doc)
    write_json_gz(second, doc)
    assert first.read_bytes() == second.read_bytes()  # no time in the gzip header
    assert first.read_bytes()[4:8] == bytes(4)  # MTIME 0, whatever second the call lands in
    assert read_json(first) == {"a": 0.1, "b": [0, 1, 2], "c": str(tmp_path), "d": [1.5, None]}
    (tmp_path / "plain.json").write_text('{"x": 1}')
    assert read_json(tmp_path / "plain.json") == {"x": 1}


@pytest.mark.parametrize(
    ("name", "data", "said"),
    [
        ("cut.json.gz", b"\x1f\x8b\x08\x00", "not gzipped JSON"),
        ("text.json.gz", b"{}", "not gzipped JSON"),
        ("bad.json", b"{nope", "not JSON"),
        ("latin.json", b"\xff", "not JSON"),
    ],
)
def test_a_file_that_is_not_json_is_a_value_error_naming_it(
    tmp_path: Path, name: str, data: bytes, said: str
) -> None:
    (tmp_path / name).write_bytes(data)
    with pytest.raises(ValueError, match=f"{name}: {said}"):
        read_json(tmp_path / name)


def test_json_default_names_what_it_cannot_write() -> None:
    assert json_default(np.int64(3)) == 3 and json_default(Path("a/b")) == "a/b"
    with pytest.raises(TypeError, match="not JSON-serialisable: set"):
        json_default({1})


def _npz_bytes(**arrays: np.ndarray) -> io.BytesIO:
    fh = io.BytesIO()
    np.savez(fh, **arrays)
    fh.seek(0)
    return fh


def test_load_npz_reads_archives_even_an_empty_one() -> None:
    with load_npz(_npz_bytes(a=np.arange(3))) as data:
        assert data.files == ["a"] and data["a"].tolist() == [0, 1, 2]
    with load_npz(_npz_bytes()) as data:  # starts with the end-of-archive record, PK\x05\x06
        assert data.files == []


def test_load_npz_never_unpickles() -> None:
    with load_npz(_npz_bytes(a=np.array([{"x": 1}], dtype=object))) as data:
        with pytest.raises(ValueError, match="allow_pickle=False"):
            data["a"]


@pytest.mark.parametrize(
    ("data", "said"),
    [
        (b"", "an empty file"),
        (None, "a lone .npy array"),
        (bytes(range(256)), "neither a zip archive nor a .npy array"),
    ],
)
def test_load_npz_refuses_what_is_not_an_archive(data: bytes | None, said: str) -> None:
    fh = io.BytesIO()
    if data is None:
        np.save(fh, np.zeros(3))
    else:
        fh.write(data)
    fh.seek(0)
    with pytest.raises(ValueError, match=f"not an .npz archive \\({said}\\)"):
        load_npz(fh)
