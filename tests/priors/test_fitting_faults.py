"""fit_prior's cache key and settings, with a tiny prior module written here (no real fit)."""

from __future__ import annotations

import dataclasses
import importlib.util
import json
import types
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from baselines.priors.fitting import _fingerprint, code_digest, fit_prior
from humotion_gym.body import default_shape
from humotion_gym.mocap.library import CacheWarning
from humotion_gym.mocap.motion import Motion


def tiny_prior() -> types.ModuleType:
    """A prior whose fit records its arguments and returns them (and one draw of its rng)."""
    module = types.ModuleType("tiny_prior_for_tests")
    calls: list[dict[str, Any]] = []

    def fit(motions, free=None, rng=None, n_iter=20, rate=0.5):
        calls.append({"n_iter": n_iter, "rate": rate, "free": free, "clips": len(motions)})
        return {"draw": np.array([rng.random()]), "n_iter": np.array(n_iter)}

    def save(fitted, path):
        np.savez(path, **fitted)

    def load(path):
        with np.load(path) as data:
            return {k: data[k] for k in data.files}

    module.fit, module.save, module.load, module.calls = fit, save, load, calls
    return module


def _clip(k: int, n: int = 12) -> Motion:
    params = np.random.default_rng(k).standard_normal((n, 25))
    return Motion(
        clip_id=f"tiny/{k}", params=params, velocities=np.zeros((n, 25)),
        observed=np.ones((n, 25), dtype=bool), fps=30.0, shape=default_shape(),
        keypoints=np.zeros((n, 15, 3)), subject="s", label="walk", source="test",
    )  # fmt: skip


@pytest.fixture(scope="module")
def clips() -> list[Motion]:
    return [_clip(k) for k in range(3)]


def _fit(
    module: types.ModuleType, clips: list[Motion], cache: Path, free: Any = None, **settings: Any
) -> Any:
    return fit_prior(module, clips, free, settings or None, cache_dir=cache, log=None)[1]


def test_a_whole_number_given_as_a_float_is_the_defaults_count(clips, tmp_path) -> None:
    """``n_iter=20.0`` reaches the fit as the int 20 and reads the default's entry."""
    module = tiny_prior()
    _fit(module, clips, tmp_path)
    got = _fit(module, clips, tmp_path, n_iter=20.0)
    assert len(module.calls) == 1 and int(got["n_iter"]) == 20  # read, not refitted
    _fit(module, clips, tmp_path, n_iter=7.0)
    assert module.calls[-1]["n_iter"] == 7 and type(module.calls[-1]["n_iter"]) is int
    # A float setting stays a float, whole or not.
    _fit(module, clips, tmp_path, rate=2.0)
    _fit(module, clips, tmp_path, rate=0.25)
    assert [c["rate"] for c in module.calls[-2:]] == [2.0, 0.25]
    assert type(module.calls[-2]["rate"]) is float


@pytest.mark.parametrize(
    ("settings", "says"),
    [
        ({"n_iter": 2.5}, "the setting n_iter must be a whole number, got 2.5"),
        ({"rate": "abc"}, "the setting rate is a number, got 'abc'"),
    ],
)
def test_settings_of_the_wrong_kind_are_refused_by_name(clips, tmp_path, settings, says) -> None:
    """A count that is not whole, a word for a number: refused before any fit."""
    module = tiny_prior()
    with pytest.raises(ValueError, match=f"tiny_prior_for_tests prior: {says}"):
        fit_prior(module, clips, None, settings, cache_dir=tmp_path, log=None)
    assert module.calls == []


def test_given_settings_free_parameters_and_clips_each_make_another_fit(clips, tmp_path) -> None:
    """Every part of what a fit is of is in its key: a change refits, the same reads."""
    module = tiny_prior()
    _fit(module, clips, tmp_path)
    _fit(module, clips, tmp_path, n_iter=5)
    assert module.calls[-1]["n_iter"] == 5 and len(module.calls) == 2
    _fit(module, clips, tmp_path, free=[6, 7])
    _fit(module, clips, tmp_path, free=[6, 8])
    assert len(module.calls) == 4
    other = [clips[0], dataclasses.replace(clips[1], label="other"), clips[2]]
    _fit(module, other, tmp_path)
    assert len(module.calls) == 5
    for free, settings in ((None, {}), (None, {"n_iter": 5}), ([6, 8], {})):  # all read back
        _fit(module, clips, tmp_path, free=free, **settings)
    assert len(module.calls) == 5


def test_every_fit_draws_from_the_same_seed(clips, tmp_path) -> None:
    """Uncached fits of the same prior are the same fit (the rng is seeded)."""
    module = tiny_prior()
    draws = [fit_prior(module, clips, None, use_cache=False, log=None)[1]["draw"] for _ in range(2)]
    np.testing.assert_array_equal(draws[0], draws[1])


def test_the_fingerprint_holds_every_clips_motion_mask_and_rate(clips) -> None:
    """A clip changed in its parameters, its observed mask or its frame rate is other data."""
    m = clips[1]
    params = m.params.copy()
    params[3, 7] += 1e-9
    observed = np.array(m.observed, dtype=bool).copy()
    observed[5, 8] = not observed[5, 8]
    base = _fingerprint(clips)
    for changed in (
        dataclasses.replace(m, params=params),
        dataclasses.replace(m, observed=observed),
        dataclasses.replace(m, fps=2 * m.fps),
    ):
        assert _fingerprint([clips[0], changed, clips[2]]) != base


def test_the_code_digest_reads_every_python_file_beside_the_module_but_hidden_ones(
    tmp_path,
) -> None:
    """A private helper beside the prior is its code; an editor's hidden backup is not."""
    (tmp_path / "my_prior.py").write_text("X = 1\n")
    (tmp_path / "_helper.py").write_text("Y = 1\n")
    spec = importlib.util.spec_from_file_location("my_prior_for_digest", tmp_path / "my_prior.py")
    module = importlib.util.module_from_spec(spec)
    before = code_digest(module)
    (tmp_path / ".#my_prior.py").write_text("an editor's lock")
    assert code_digest(module) == before
    (tmp_path / "_helper.py").write_text("Y = 2\n")
    assert code_digest(module) != before
    assert code_digest(types.ModuleType("in_memory")) == "none"


def test_an_entry_whose_arrays_were_changed_is_refitted_not_read(clips, tmp_path) -> None:
    """Arrays rewritten under the entry's own header: the digest tells, the fit is redone."""
    module = tiny_prior()
    fitted = _fit(module, clips, tmp_path)
    (path,) = (tmp_path / "priors").glob("*.npz")
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files}
    arrays["draw"] = arrays["draw"] + 1.0
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)
    with pytest.warns(CacheWarning, match="do not match the header's digest"):
        again = _fit(module, clips, tmp_path)
    assert len(module.calls) == 2
    np.testing.assert_array_equal(again["draw"], fitted["draw"])


def test_an_entry_of_other_code_under_the_right_name_is_refitted(clips, tmp_path) -> None:
    """The header's code digest is checked on reading, like every other part of the key."""
    module = tiny_prior()
    _fit(module, clips, tmp_path)
    (path,) = (tmp_path / "priors").glob("*.npz")
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files}
    header = json.loads(str(arrays["__cache__"]))
    header["code"] = "0123456789abcdef"
    arrays["__cache__"] = np.array(json.dumps(header))
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)
    with pytest.warns(CacheWarning, match="foreign entry: code='0123456789abcdef'"):
        _fit(module, clips, tmp_path)
    assert len(module.calls) == 2


@pytest.mark.parametrize("free", [[6.7, 7.2], [True, False], ["6"], [2**70], [[6, 7]], [6, 6]])
def test_free_that_is_not_distinct_indices_is_refused_in_the_fits_words(
    clips, tmp_path, free
) -> None:
    """Floats, bools, words, a number past any index: refused before any fit, never cut."""
    module = tiny_prior()
    with pytest.raises(ValueError, match=r"tiny_prior_for_tests\.fit: free must be distinct"):
        fit_prior(module, clips, free, cache_dir=tmp_path, log=None)
    assert module.calls == [] and not (tmp_path / "priors").exists()


def test_fit_prior_refuses_free_as_the_priors_own_fit_does(clips) -> None:
    """The same check and the same words as ``constant_velocity.fit``'s."""
    from baselines.priors import constant_velocity

    with pytest.raises(ValueError) as direct:
        constant_velocity.fit(clips, free=[6.7, 7.2])
    with pytest.raises(ValueError) as through:
        fit_prior("constant_velocity", clips, [6.7, 7.2], use_cache=False, log=None)
    assert str(through.value) == str(direct.value)


def test_a_count_that_may_be_none_takes_a_whole_float_as_an_int(clips, tmp_path) -> None:
    """``depth: int | None = None`` (as ``tree.fit`` writes it): 5.0 is 5, 5.5 is refused."""
    module = tiny_prior()

    def fit(motions, free=None, rng=None, depth: int | None = None, scale: float | None = None):
        module.calls.append({"depth": depth, "scale": scale})
        return {"depth": np.array(-1 if depth is None else depth)}

    module.fit = fit
    _fit(module, clips, tmp_path, depth=5)
    got = _fit(module, clips, tmp_path, depth=5.0)
    assert len(module.calls) == 1 and int(got["depth"]) == 5  # the same entry, read
    _fit(module, clips, tmp_path, depth=6.0, scale=2.0)
    assert module.calls[-1] == {"depth": 6, "scale": 2.0}
    assert type(module.calls[-1]["depth"]) is int and type(module.calls[-1]["scale"]) is float
    with pytest.raises(ValueError, match="the setting depth must be a whole number, got 5.5"):
        _fit(module, clips, tmp_path, depth=5.5)
    # An annotation that is the type itself (a module without postponed annotations).
    fit.__annotations__ = {"depth": int | None, "scale": float | None}
    _fit(module, clips, tmp_path, depth=7.0)
    assert module.calls[-1]["depth"] == 7 and type(module.calls[-1]["depth"]) is int
