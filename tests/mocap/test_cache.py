"""The clip cache heals: every damaged, foreign or misplaced entry is reported once and rebuilt.

Clips are small BVH files written from the synthetic motions
(:func:`humotion_gym.mocap.export.write_motion_bvh`), never copies of real data.
"""

from __future__ import annotations

import json
import os
import shutil
import threading
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

import humotion_gym._version
from humotion_gym.mocap import library as lib_mod
from humotion_gym.mocap.export import write_motion_bvh
from humotion_gym.mocap.library import (
    CacheWarning,
    MotionLibrary,
    find_clips,
    load_library,
    synthetic_library,
)
from humotion_gym.mocap.motion import Motion
from tests.cache_corruptions import FILE_CORRUPTIONS, flip_stored_byte

FRAMES = 40


@pytest.fixture
def data(tmp_path: Path) -> Path:
    """A folder of two short BVH clips."""
    folder = tmp_path / "data"
    folder.mkdir()
    lib = synthetic_library()
    for name, clip in (("take_a", "synthetic/walk-01"), ("take_b", "synthetic/run-01")):
        m = lib[clip].slice(0, FRAMES)
        write_motion_bvh(folder / f"{name}.bvh", m.params, m.shape, m.fps)
    return folder


def _load(data: Path, cache: Path) -> MotionLibrary:
    return load_library([data], cache_dir=cache, progress=False)


def _entry(data: Path, cache: Path, clip: str = "take_a") -> Path:
    """The natural cache file of one clip."""
    src = next(s for s in find_clips([data]) if s.path.stem == clip)
    place, key = lib_mod._cache_place(src, 30.0), lib_mod._cache_key(src, 30.0)
    return cache / "clips" / f"{place}-{key}.npz"


def _assert_same(got: MotionLibrary, want: MotionLibrary) -> None:
    assert got.clip_ids == want.clip_ids
    for a, b in zip(got, want, strict=True):
        for name in ("params", "velocities", "observed"):
            assert np.array_equal(getattr(a, name), getattr(b, name)), name
        assert np.allclose(a.keypoints, b.keypoints, equal_nan=True, atol=1e-3)
        assert a.shape == b.shape
        for name in ("fps", "subject", "label", "source", "dataset", "description", "meta"):
            assert getattr(a, name) == getattr(b, name), name


def _no_warning_load(data: Path, cache: Path, monkeypatch) -> MotionLibrary:
    """Load with every CacheWarning an error, checking that nothing is parsed."""
    parsed: list[object] = []
    real = lib_mod.load_clip
    monkeypatch.setattr(lib_mod, "load_clip", lambda *a, **k: parsed.append(a) or real(*a, **k))
    with warnings.catch_warnings():
        warnings.simplefilter("error", CacheWarning)
        out = _load(data, cache)
    monkeypatch.setattr(lib_mod, "load_clip", real)
    assert parsed == []
    return out


# -- the corruptions: each turns a good entry at ``path`` into a bad one --------------


def _flip_byte(path: Path, ctx: dict) -> None:
    """Flip one byte inside the stored data of the params array."""
    flip_stored_byte(path, "params.npy")


def _npy_in_place(path: Path, ctx: dict) -> None:
    with open(path, "wb") as fh:
        np.save(fh, np.zeros((FRAMES, 25)))


def _rewrite(path: Path, change: Callable[[dict, dict], None]) -> None:
    with np.load(path, allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files}
    header = json.loads(str(arrays.pop("header")))
    change(header, arrays)
    with open(path, "wb") as fh:
        np.savez(fh, header=np.array(json.dumps(header)), **arrays)


def _header_wrong_types(path: Path, ctx: dict) -> None:
    def change(header: dict, arrays: dict) -> None:
        header["fps"] = "30"
        header["clip_id"] = 7

    _rewrite(path, change)


def _arrays_wrong_dtypes(path: Path, ctx: dict) -> None:
    def change(header: dict, arrays: dict) -> None:
        arrays["params"] = arrays["params"].astype(str)
        arrays["observed"] = arrays["observed"].astype(np.float64)

    _rewrite(path, change)


def _arrays_changed_under_header(path: Path, ctx: dict) -> None:
    """Right types, wrong data: the header's digest no longer matches."""

    def change(header: dict, arrays: dict) -> None:
        arrays["params"] = arrays["params"] + 0.1

    _rewrite(path, change)


def _other_clip(path: Path, ctx: dict) -> None:
    shutil.copyfile(_entry(ctx["data"], ctx["cache"], "take_b"), path)


def _other_version(path: Path, ctx: dict) -> None:
    """An entry written by another package version, copied over this version's name."""
    mp: pytest.MonkeyPatch = ctx["monkeypatch"]
    old_cache = ctx["cache"].parent / "old-cache"
    mp.setattr(humotion_gym._version, "__version__", "0.0.0-old")
    _load(ctx["data"], old_cache)
    old_entry = _entry(ctx["data"], old_cache)
    mp.undo()
    assert old_entry.name != path.name  # the version is part of the key
    shutil.copyfile(old_entry, path)


CORRUPTIONS: dict[str, Callable[[Path, dict], None]] = {
    **FILE_CORRUPTIONS,
    "flipped-byte": _flip_byte,
    "npy-in-place": _npy_in_place,
    "header-wrong-types": _header_wrong_types,
    "arrays-wrong-dtypes": _arrays_wrong_dtypes,
    "arrays-changed": _arrays_changed_under_header,
    "other-clip": _other_clip,
    "other-version": _other_version,
}


@pytest.mark.parametrize("corruption", list(CORRUPTIONS))
def test_a_bad_entry_is_reported_once_and_rebuilt(data, tmp_path, monkeypatch, corruption):
    cache = tmp_path / "cache"
    fresh = load_library([data], use_cache=False, progress=False)
    _assert_same(_load(data, cache), fresh)
    path = _entry(data, cache)
    CORRUPTIONS[corruption](path, {"data": data, "cache": cache, "monkeypatch": monkeypatch})

    with pytest.warns(CacheWarning) as record:
        healed = _load(data, cache)
    messages = [str(w.message) for w in record if issubclass(w.category, CacheWarning)]
    assert len(messages) == 1, messages
    assert path.name in messages[0] and "rebuilding" in messages[0]
    _assert_same(healed, fresh)

    # Healed: the next load reads the cache silently and parses nothing.
    _assert_same(_no_warning_load(data, cache, monkeypatch), fresh)
    if corruption == "full-directory":
        assert (path / "someone's file").read_text() == "keep me"
    else:
        assert path.is_file()
    assert not list((cache / "clips").glob(".*.tmp"))


def test_messages_say_what_was_wrong(data, tmp_path):
    cache = tmp_path / "cache"
    _load(data, cache)
    path = _entry(data, cache)
    shutil.copyfile(_entry(data, cache, "take_b"), path)
    with pytest.warns(CacheWarning, match=r"foreign entry: .*clip_id='user/data/take_b'"):
        _load(data, cache)
    path.write_bytes(b"")
    with pytest.warns(CacheWarning, match=r"bad entry of user/data/take_a: .*an empty file"):
        _load(data, cache)
    # bytes of nothing numpy knows: said so, not numpy's advice to unpickle them
    path.write_bytes(bytes(range(256)))
    with pytest.warns(CacheWarning, match=r"neither a zip archive nor a .npy array") as caught:
        _load(data, cache)
    assert not any("pickle" in str(w.message) for w in caught)


def test_an_entry_of_the_file_before_it_changed_is_not_read_for_it(data, tmp_path):
    cache = tmp_path / "cache"
    _load(data, cache)
    before = _entry(data, cache)
    clip = data / "take_a.bvh"
    stat = clip.stat()  # changed in place: same size, later time (a re-export, a fix)
    os.utime(clip, ns=(stat.st_atime_ns, stat.st_mtime_ns + 10**9))
    after = _entry(data, cache)
    assert after.name.split("-")[0] == before.name.split("-")[0]  # the same place
    assert after != before  # the file's time is part of the key
    shutil.copyfile(before, after)  # the old entry under the new key's name
    with pytest.warns(CacheWarning, match=r"foreign entry: key='[0-9a-f]{32}' \(expected"):
        _load(data, cache)


def test_a_legacy_entry_beside_its_placed_one_is_not_moved_over_it(data, tmp_path, monkeypatch):
    cache = tmp_path / "cache"
    _load(data, cache)
    path = _entry(data, cache)
    src = next(s for s in find_clips([data]) if s.path.stem == "take_a")
    legacy = cache / "clips" / f"{lib_mod._cache_key(src, 30.0)}.npz"
    legacy.write_bytes(b"")  # a damaged entry left under the name from before places
    good = path.read_bytes()
    _no_warning_load(data, cache, monkeypatch)  # the placed entry is read as it is
    assert path.read_bytes() == good


def test_the_key_holds_the_package_version(data, tmp_path, monkeypatch):
    cache = tmp_path / "cache"
    src = find_clips([data])[0]
    key = lib_mod._cache_key(src, 30.0)
    monkeypatch.setattr(humotion_gym._version, "__version__", "99.0")
    assert lib_mod._cache_key(src, 30.0) != key
    _load(data, cache)
    monkeypatch.undo()
    # An upgrade never reuses the other version's entries: every clip is parsed again.
    parsed: list[object] = []
    real = lib_mod.load_clip
    monkeypatch.setattr(lib_mod, "load_clip", lambda *a, **k: parsed.append(a) or real(*a, **k))
    _load(data, cache)
    assert len(parsed) == 2


def test_an_unwritable_cache_reports_and_loads(data, tmp_path):
    cache = tmp_path / "cache"
    cache.mkdir()
    (cache / "clips").write_text("a file where the folder should be")
    fresh = load_library([data], use_cache=False, progress=False)
    with pytest.warns(
        CacheWarning, match=r"clips cannot be made \(.*clips is a file, not a folder\)"
    ) as record:
        got = _load(data, cache)
    _assert_same(got, fresh)
    # one warning for the folder, not one per clip, and none when loaded again
    assert len([w for w in record if issubclass(w.category, CacheWarning)]) == 1
    with warnings.catch_warnings():
        warnings.simplefilter("error", CacheWarning)
        _assert_same(_load(data, cache), fresh)


def test_a_cache_under_a_file_says_so_in_words(data, tmp_path):
    """A cache folder set to a file: the warning says so, not ``[Errno 20]``."""
    cache = tmp_path / "a-file"
    cache.write_text("a file where the cache folder should be")
    with pytest.warns(CacheWarning) as record:
        _load(data, cache)
    (message,) = [str(w.message) for w in record if issubclass(w.category, CacheWarning)]
    assert f"{cache} is a file, not a folder" in message and "nothing is cached" in message
    assert "Errno" not in message


def test_a_tilde_in_the_cache_variable_is_the_home_folder(monkeypatch, tmp_path):
    """``HUMOTION_CACHE='~/x'`` (quoted, so no shell expanded it) is under home, not ``./~``."""
    from humotion_gym.mocap.library import default_cache_dir

    monkeypatch.setenv("HOME", str(tmp_path))
    monkeypatch.setenv("HUMOTION_CACHE", "~/foo")
    assert default_cache_dir() == tmp_path / "foo"
    monkeypatch.delenv("HUMOTION_CACHE")
    monkeypatch.setenv("XDG_CACHE_HOME", "~/xdg")
    assert default_cache_dir() == tmp_path / "xdg" / "humotion_gym"


def test_concurrent_loads_share_the_cache(data, tmp_path):
    cache = tmp_path / "cache"
    fresh = load_library([data], use_cache=False, progress=False)
    results: list[MotionLibrary] = []
    errors: list[BaseException] = []

    def work() -> None:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("error", CacheWarning)
                results.append(_load(data, cache))
        except BaseException as exc:  # noqa: BLE001 - handed to the main thread
            errors.append(exc)

    threads = [threading.Thread(target=work) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert errors == [] and len(results) == 4
    for got in results:
        _assert_same(got, fresh)
    assert len(list((cache / "clips").glob("*.npz"))) == 2
    assert not list((cache / "clips").glob(".*.tmp"))


def test_motion_load_rejects_what_is_not_a_motion(tmp_path):
    m = synthetic_library()["synthetic/walk-01"].slice(0, 10)
    m.save(tmp_path / "m.npz", extra={"key": "k"})
    back, extra = Motion.load_with_extra(tmp_path / "m.npz")
    assert extra == {"key": "k"} and np.array_equal(back.params, m.params)
    np.save(tmp_path / "a.npy", np.zeros(3))
    (tmp_path / "d.npz").mkdir()
    for bad in (tmp_path / "a.npy", tmp_path / "d.npz", tmp_path / "absent.npz"):
        with pytest.raises(ValueError, match="not a saved Motion"):
            Motion.load(bad)


def _parsed_clips(monkeypatch: pytest.MonkeyPatch) -> list[object]:
    parsed: list[object] = []
    real = lib_mod.load_clip
    monkeypatch.setattr(lib_mod, "load_clip", lambda *a, **k: parsed.append(a) or real(*a, **k))
    return parsed


def test_a_changed_file_or_version_leaves_one_entry_per_clip(data, tmp_path, monkeypatch):
    """Each changed file or new version used to add an entry beside the stale one."""
    cache = tmp_path / "cache"
    _load(data, cache)
    entries = sorted((cache / "clips").glob("*.npz"))
    assert len(entries) == 2
    for k, path in enumerate(sorted(data.iterdir())):  # touched, as a copy or download does
        stat = path.stat()
        os.utime(path, ns=(stat.st_atime_ns, stat.st_mtime_ns + 10**9 * (k + 1)))
    _load(data, cache)
    monkeypatch.setattr(humotion_gym._version, "__version__", "99.0")
    _load(data, cache)
    now = sorted((cache / "clips").glob("*.npz"))
    assert len(now) == 2 and not set(now) & set(entries)  # rebuilt, and the stale gone
    assert {p.name.split("-")[0] for p in now} == {p.name.split("-")[0] for p in entries}


def test_an_entry_under_its_name_before_places_is_read_not_parsed(data, tmp_path, monkeypatch):
    cache = tmp_path / "cache"
    _load(data, cache)
    for src in find_clips([data]):  # back to the old names, KEY.npz
        key = lib_mod._cache_key(src, 30.0)
        place = lib_mod._cache_place(src, 30.0)
        (cache / "clips" / f"{place}-{key}.npz").rename(cache / "clips" / f"{key}.npz")
    parsed = _parsed_clips(monkeypatch)
    _load(data, cache)
    assert parsed == []
    assert all("-" in p.name for p in (cache / "clips").glob("*.npz"))


def test_a_whole_number_frame_rate_shares_the_float_s_entries(data, tmp_path):
    cache = tmp_path / "cache"
    a = load_library([data], fps=30.0, cache_dir=cache, progress=False)
    entries = sorted((cache / "clips").iterdir())
    b = load_library([data], fps=30, cache_dir=cache, progress=False)  # not a second copy
    assert sorted((cache / "clips").iterdir()) == entries
    _assert_same(b, a)
