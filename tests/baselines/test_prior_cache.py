"""The prior cache heals: every damaged, foreign or misplaced fit is reported once and refitted.

Fits ``pf-cv`` (the constant-velocity prior, well under a second) on the
synthetic ``SideWalk-v2`` environment.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib
import json
import shutil
import sys
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import humotion_gym._version
from baselines import agents as agents_mod
from baselines.agents import AGENTS, fit_prior
from humotion_gym.envs.pose_tracking import PoseTrackingEnv
from humotion_gym.mocap.library import CacheWarning
from tests.cache_corruptions import FILE_CORRUPTIONS, flip_stored_byte

# The plain constant-velocity prior (no registered settings): its fit defaults are the key's.
SPEC = agents_mod.AgentSpec(AGENTS["pf-cv"].prior)


@pytest.fixture(scope="module")
def env() -> PoseTrackingEnv:
    return gym.make("humotion_gym/SideWalk-v2").unwrapped  # type: ignore[return-value]


@pytest.fixture(scope="module")
def fresh(env: PoseTrackingEnv) -> Any:
    return fit_prior(SPEC, env, use_cache=False)[1]


def _fit(env: PoseTrackingEnv, cache: Path, **settings: Any) -> Any:
    return fit_prior(SPEC, env, settings=settings or None, cache_dir=cache)[1]


def _entries(cache: Path) -> list[Path]:
    return sorted((cache / "priors").glob("*.npz"))


def _assert_same(got: Any, want: Any) -> None:
    assert type(got) is type(want)
    for f in dataclasses.fields(want):
        a, b = getattr(got, f.name), getattr(want, f.name)
        assert np.array_equal(np.asarray(a), np.asarray(b)), f.name
        assert np.asarray(a).dtype == np.asarray(b).dtype, f.name


def _no_warning_fit(env: PoseTrackingEnv, cache: Path, monkeypatch) -> Any:
    """Fit with every CacheWarning an error, checking that the cache answers."""
    module = importlib.import_module(SPEC.prior)
    calls: list[object] = []
    real = module.fit

    @functools.wraps(real)  # the same signature, so the same cache key
    def counting_fit(*args: Any, **kwargs: Any) -> Any:
        calls.append(args)
        return real(*args, **kwargs)

    monkeypatch.setattr(module, "fit", counting_fit)
    with warnings.catch_warnings():
        warnings.simplefilter("error", CacheWarning)
        out = _fit(env, cache)
    monkeypatch.setattr(module, "fit", real)
    assert calls == []
    return out


# -- the corruptions ---------------------------------------------------------------------


def _flip_byte(path: Path, ctx: dict) -> None:
    """Flip one byte inside the stored data of the accel_std array."""
    flip_stored_byte(path, "accel_std.npy", -3)


def _npy_in_place(path: Path, ctx: dict) -> None:
    with open(path, "wb") as fh:
        np.save(fh, np.zeros(8))


def _rewrite(path: Path, change: Callable[[dict, dict], None]) -> None:
    with np.load(path, allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files}
    header = json.loads(str(arrays.pop("__cache__")))
    change(header, arrays)
    with open(path, "wb") as fh:
        np.savez(fh, __cache__=np.array(json.dumps(header)), **arrays)


def _header_wrong_types(path: Path, ctx: dict) -> None:
    def change(header: dict, arrays: dict) -> None:
        header["key"] = 12345
        header["cache_version"] = 1

    _rewrite(path, change)


def _header_not_an_object(path: Path, ctx: dict) -> None:
    with np.load(path, allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files if k != "__cache__"}
    with open(path, "wb") as fh:
        np.savez(fh, __cache__=np.arange(3), **arrays)


def _arrays_wrong_dtypes(path: Path, ctx: dict) -> None:
    def change(header: dict, arrays: dict) -> None:
        arrays["free"] = arrays["free"].astype(np.float64)
        arrays["accel_std"] = arrays["accel_std"].astype(str)

    _rewrite(path, change)


def _other_kind(path: Path, ctx: dict) -> None:
    """Another prior's parameters under a copied header (the digest no longer matches)."""

    def change(header: dict, arrays: dict) -> None:
        arrays["__kind__"] = np.array("TreeParams")

    _rewrite(path, change)


def _other_settings(path: Path, ctx: dict) -> None:
    """The entry of a fit with other settings, copied over this one's name."""
    _fit(ctx["env"], ctx["cache"], multiplier=2.0)
    other = next(p for p in _entries(ctx["cache"]) if p != path)
    shutil.copyfile(other, path)
    other.unlink()


def _other_version(path: Path, ctx: dict) -> None:
    """An entry written by another package version, copied over this version's name."""
    mp: pytest.MonkeyPatch = ctx["monkeypatch"]
    old_cache = ctx["cache"].parent / "old-cache"
    mp.setattr(humotion_gym._version, "__version__", "0.0.0-old")
    _fit(ctx["env"], old_cache)
    mp.undo()
    (old_entry,) = _entries(old_cache)
    assert old_entry.name != path.name  # the version is part of the key
    shutil.copyfile(old_entry, path)


CORRUPTIONS: dict[str, Callable[[Path, dict], None]] = {
    **FILE_CORRUPTIONS,
    "flipped-byte": _flip_byte,
    "npy-in-place": _npy_in_place,
    "header-wrong-types": _header_wrong_types,
    "header-not-an-object": _header_not_an_object,
    "arrays-wrong-dtypes": _arrays_wrong_dtypes,
    "other-kind": _other_kind,
    "other-settings": _other_settings,
    "other-version": _other_version,
}


@pytest.mark.parametrize("corruption", list(CORRUPTIONS))
def test_a_bad_entry_is_reported_once_and_refitted(env, fresh, tmp_path, monkeypatch, corruption):
    cache = tmp_path / "cache"
    _assert_same(_fit(env, cache), fresh)
    (path,) = _entries(cache)
    ctx = {"env": env, "cache": cache, "monkeypatch": monkeypatch}
    CORRUPTIONS[corruption](path, ctx)

    with pytest.warns(CacheWarning) as record:
        healed = _fit(env, cache)
    messages = [str(w.message) for w in record if issubclass(w.category, CacheWarning)]
    assert len(messages) == 1, messages
    assert path.name in messages[0] and "refitting" in messages[0]
    _assert_same(healed, fresh)

    # Healed: the next call reads the cache silently and fits nothing.
    _assert_same(_no_warning_fit(env, cache, monkeypatch), fresh)
    if corruption == "full-directory":
        assert (path / "someone's file").read_text() == "keep me"
    else:
        assert path.is_file()
    assert not list((cache / "priors").glob(".*.tmp"))


def test_a_good_entry_is_read_without_refitting(env, fresh, tmp_path, monkeypatch):
    cache = tmp_path / "cache"
    _fit(env, cache)
    _assert_same(_no_warning_fit(env, cache, monkeypatch), fresh)


def test_the_key_holds_the_package_version_and_the_fit_defaults(env, tmp_path, monkeypatch):
    cache = tmp_path / "cache"
    _fit(env, cache)
    before = _entries(cache)
    monkeypatch.setattr(humotion_gym._version, "__version__", "99.0")
    _fit(env, cache)
    monkeypatch.undo()
    after = _entries(cache)  # an upgrade refits instead of reusing, and its entry replaces
    assert len(before) == len(after) == 1 and before != after  # the stale one (same place)
    assert before[0].name.rsplit("-", 1)[0] == after[0].name.rsplit("-", 1)[0]

    # A fit whose default changes (a new release of the fitting code) refits too.
    module = importlib.import_module(SPEC.prior)
    real = module.fit

    def fit_with_new_default(motions, free=None, rng=None, multiplier=1.5, frame_skip=1):
        return real(motions, free=free, rng=rng, multiplier=multiplier, frame_skip=frame_skip)

    monkeypatch.setattr(module, "fit", fit_with_new_default)
    got = _fit(env, cache)  # other settings: another place, kept beside the first
    assert got.multiplier == 1.5 and len(_entries(cache)) == 2


_USER_PRIOR = """
from baselines.priors import constant_velocity as _cv

SCALE = {scale}


def fit(motions, free=None, rng=None, multiplier=1.0):
    return _cv.fit(motions, free=free, rng=rng, multiplier=multiplier * SCALE)


initial, transition, save, load = _cv.initial, _cv.transition, _cv.save, _cv.load
"""


def test_an_edited_prior_is_refitted_not_read(env, tmp_path, monkeypatch):
    """A user's prior module edited between fits: its name and settings alike, its code not."""
    from baselines.priors.fitting import fit_prior as fit_module

    package = tmp_path / "mine_edited"
    package.mkdir()
    (package / "__init__.py").write_text("")
    source = package / "edited_prior.py"
    # an editor's lock file beside it (a dangling link) is no code to digest
    (package / ".#edited_prior.py").symlink_to(tmp_path / "nowhere")
    monkeypatch.syspath_prepend(str(tmp_path))
    # the edits are read from source: no bytecode of the first to stand in for the second
    monkeypatch.setattr(sys, "dont_write_bytecode", True)
    cache, clips = tmp_path / "cache", env.describe().training
    fits, entries = [], []
    try:
        for scale in (1.0, 2.25, 2.25):
            source.write_text(_USER_PRIOR.format(scale=scale))
            importlib.invalidate_caches()
            module = importlib.reload(importlib.import_module("mine_edited.edited_prior"))
            fits.append(fit_module(module, clips, None, cache_dir=cache, log=None)[1])
            entries.append([(p, p.stat().st_mtime_ns) for p in _entries(cache)])
    finally:
        sys.modules.pop("mine_edited.edited_prior", None)
        sys.modules.pop("mine_edited", None)
    assert [f.multiplier for f in fits] == [1.0, 2.25, 2.25]
    # the edit's fit replaced the first (the stale entry is gone), and was then read back
    assert len(entries[0]) == len(entries[1]) == 1 and entries[0] != entries[1]
    assert entries[2] == entries[1]


def test_an_unwritable_cache_reports_and_fits(env, fresh, tmp_path):
    cache = tmp_path / "cache"
    cache.mkdir()
    (cache / "priors").write_text("a file where the folder should be")
    with pytest.warns(CacheWarning, match="priors cannot be made .*is a file, not a folder"):
        got = _fit(env, cache)
    _assert_same(got, fresh)


def test_messages_say_what_was_wrong(env, tmp_path):
    cache = tmp_path / "cache"
    _fit(env, cache)
    (path,) = _entries(cache)
    path.write_bytes(b"")
    with pytest.warns(CacheWarning, match=r"bad constant_velocity entry: .*an empty file"):
        _fit(env, cache)
    _other_settings(path, {"env": env, "cache": cache})
    with pytest.warns(CacheWarning, match=r"foreign entry: .*settings="):
        _fit(env, cache)


def test_the_key_holds_the_clips_labels(env):
    """The cyclic prior fits the walking clips, the switching model one model per label."""
    from baselines.priors.fitting import _fingerprint

    clips = list(env.describe().training)[:3]
    relabelled = [dataclasses.replace(m, label=f"not-{m.label}") for m in clips]
    assert _fingerprint(clips) != _fingerprint(relabelled)
    assert _fingerprint(clips) == _fingerprint([dataclasses.replace(m) for m in clips])


def test_two_modules_of_one_name_in_two_folders_keep_their_own_fits(env, tmp_path, monkeypatch):
    """Their fits share prior, settings and data; the place holds each module's file."""
    from baselines.priors.fitting import fit_prior as fit_module

    module = importlib.import_module(SPEC.prior)
    cache, clips = tmp_path / "cache", env.describe().training
    for folder in ("a", "b"):
        monkeypatch.setattr(module, "__file__", str(tmp_path / folder / "constant_velocity.py"))
        fit_module(module, clips, None, cache_dir=cache, log=None)
    assert len(_entries(cache)) == 2
