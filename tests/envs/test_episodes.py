"""The declared test episodes: the shipped lists are the rule's, and the rule's contract."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from humotion_gym.envs import episodes as ep
from humotion_gym.envs.tasks import get_task
from humotion_gym.mocap.library import (
    TEST_SUBJECTS,
    MotionLibrary,
    find_clips,
    load_library,
    synthetic_library,
)
from humotion_gym.mocap.motion import Motion

TASKS = tuple(ep.PER_CLIP)


@pytest.fixture(scope="module")
def synthetic() -> MotionLibrary:
    return synthetic_library()


@pytest.fixture(scope="module")
def cmu_test(shared_mocap: Path) -> MotionLibrary:
    """The shared motion capture's test persons only (the lists read nothing else)."""
    test = [s.path for s in find_clips([shared_mocap]) if s.subject in TEST_SUBJECTS]
    return load_library(test, fps=30.0, progress=False)


def _check_rule(task: str, library: MotionLibrary, source: str) -> None:
    assert ep.source_of(library) == source
    shipped = ep.declared_episodes(task, source)
    assert list(shipped) == ep.make_windows(ep.task_spec(task), library, ep.PER_CLIP[task])
    ep.check_windows(shipped, library, ep.window_frames(ep.task_spec(task)))


@pytest.mark.parametrize("task", TASKS)
def test_the_shipped_synthetic_lists_are_the_rules(task, synthetic):
    _check_rule(task, synthetic, "synthetic")


@pytest.mark.mocap
@pytest.mark.parametrize("task", TASKS)
def test_the_shipped_cmu_lists_are_the_rules(task, cmu_test):
    _check_rule(task, cmu_test, "cmu")


@pytest.mark.parametrize("task", TASKS)
@pytest.mark.parametrize("source", ["synthetic", "cmu"])
def test_windows_are_disjoint_observed_and_cover_every_qualifying_clip(task, source, synthetic):
    spec = ep.task_spec(task)
    span = ep.window_frames(spec)
    windows = ep.declared_episodes(task, source)
    assert windows, f"{task}/{source}: an empty list"
    by_clip: dict[str, list[int]] = {}
    for w in windows:
        by_clip.setdefault(w.clip_id, []).append(w.start)
    for clip, starts in by_clip.items():
        s = np.sort(starts)
        assert np.all(np.diff(s) >= span), f"{task}/{source} {clip}: windows share a frame"
        assert len(starts) <= ep.PER_CLIP[task]
    if source == "synthetic":
        clips = ep.qualifying_clips(spec, synthetic)
        assert clips and sorted(by_clip) == sorted(m.clip_id for m in clips)
        for w in windows:
            assert synthetic[w.clip_id].frame_observed[w.start : w.start + span].all()
            assert w.person == synthetic[w.clip_id].subject


@pytest.mark.parametrize(
    "name", ["ArmTrack", "ArmTrack-v1", "ArmTrack-v2", "humotion_gym/ArmTrack-v1"]
)
def test_task_names_with_or_without_version_name_one_list(name):
    assert ep.declared_episodes(name, "cmu") == ep.declared_episodes("ArmTrack", "cmu")


def test_unknown_task_or_source_is_refused():
    with pytest.raises(KeyError, match="Unknown"):
        ep.declared_episodes("Unknown-v1", "cmu")
    with pytest.raises(KeyError, match="source"):
        ep.declared_episodes("ArmTrack", "bandai")


def _motion(observed: np.ndarray, clip_id: str = "user/x") -> Motion:
    """A user's clip of ``observed.size`` frames (a synthetic clip's motion, relabelled)."""
    m = synthetic_library()[0].slice(0, observed.size)
    mask = np.repeat(observed[:, None], m.params.shape[1], axis=1)
    return dataclasses.replace(
        m, clip_id=clip_id, observed=mask, dataset="user", synthetic=False, subject="user-x"
    )


def test_spread_starts_avoids_unobserved_frames_and_keeps_windows_apart():
    # 100 frames, 11 to 19 unobserved: windows of 10 fit in 0..10 and 20..99
    observed = np.ones(100, bool)
    observed[11:20] = False
    m = _motion(observed)
    good = ep.observed_starts(m, 10)
    assert good.tolist() == [0, 1] + list(range(20, 91))
    starts = ep.spread_starts(good, 10, 5)
    assert len(starts) == 5 and starts[0] == 0 and starts[-1] == 90
    assert np.all(np.diff(starts) >= 10)
    assert all(not (s < 20 and s + 10 > 11) for s in starts)
    # as many as fit: 1 in 0..10, 8 in 20..99
    assert len(ep.spread_starts(good, 10, 50)) == 9
    # evenly spread over a fully observed clip: the ends and the middle
    assert ep.spread_starts(np.arange(91), 10, 3) == [0, 45, 90]
    assert ep.spread_starts(np.arange(91), 10, 1) == [45]


def test_spread_starts_never_lets_two_windows_share_a_frame():
    # good starts 0 1 4 5 6 8, windows of 2: four fit (0, 4, 6, 8); aiming at
    # 5.33 the third must not take 5, which shares frame 5 with the window at 4
    assert ep.spread_starts(np.array([0, 1, 4, 5, 6, 8]), 2, 5) == [0, 4, 6, 8]
    # 3 5 7 8 13: four fit; the third window may start no later than 8 (13 - 2
    # leaves 11, the latest good start at or before it is 8), and takes 8 (target 9.67)
    assert ep.spread_starts(np.array([3, 5, 7, 8, 13]), 2, 5) == [3, 5, 8, 13]
    rng = np.random.default_rng(7)
    for _ in range(300):
        good = np.flatnonzero(rng.random(int(rng.integers(5, 40))) < rng.uniform(0.3, 1.0))
        span, per_clip = int(rng.integers(2, 8)), int(rng.integers(1, 6))
        if good.size == 0:
            continue
        most, free = 0, -1  # the most disjoint windows: the earliest that fits, greedily
        for s in good.tolist():
            if s >= free:
                most, free = most + 1, s + span
        starts = ep.spread_starts(good, span, per_clip)
        assert len(starts) == min(per_clip, most)
        assert set(starts) <= set(good.tolist())
        assert np.all(np.diff(starts) >= span), (good, span, starts)


def test_source_of_names_what_it_found(synthetic):
    assert ep.source_of(synthetic) == "synthetic"
    user = _motion(np.ones(50, bool))
    mixed = MotionLibrary(synthetic.motions + (user,), TEST_SUBJECTS | {user.subject})
    with pytest.raises(ValueError, match=r"\['synthetic', 'user'\]"):
        ep.source_of(mixed)
    with pytest.raises(ValueError, match="no test clips"):
        ep.source_of(synthetic.split("train"))


def test_check_windows_fails_on_a_tampered_list(synthetic):
    windows = ep.declared_episodes("BodyTrack", "synthetic")
    span = ep.window_frames(ep.task_spec("BodyTrack"))
    ep.check_windows(windows, synthetic, span)
    w = windows[0]
    tampered = {
        f"expected {w.frames + 1} frames": dataclasses.replace(w, frames=w.frames + 1),
        "outside its": dataclasses.replace(w, start=w.frames - span + 1),
        r"window -1\.\.": dataclasses.replace(w, start=-1),  # not counted from the end
        "not in the library": dataclasses.replace(w, clip_id="synthetic/fly-05"),
        # a training clip listed as a test episode, and a clip under another person's name
        "'synthetic-01' .*not a held-out person": dataclasses.replace(
            w, clip_id="synthetic/walk-01", person="synthetic-01",
            frames=synthetic["synthetic/walk-01"].n_frames,
        ),
        "the list says 'synthetic-06'": dataclasses.replace(w, person="synthetic-06"),
    }  # fmt: skip
    for what, bad in tampered.items():
        with pytest.raises(ValueError, match=what) as caught:
            ep.check_windows(windows[1:] + (bad,), synthetic, span)
        assert repr(bad.clip_id) in str(caught.value)
    # a list made on other clips: the fingerprint (frame count) tells
    shorter = synthetic_library(fps=15.0)
    with pytest.raises(ValueError, match=w.clip_id):
        ep.check_windows(windows, shorter, span)


def test_the_rule_ignores_min_motion():
    arm = get_task("ArmTrack-v1")
    assert arm.min_motion_mm > 0
    still = dataclasses.replace(arm, min_motion_mm=0.0)
    lib = synthetic_library()
    assert ep.make_windows(arm, lib, 3) == ep.make_windows(still, lib, 3)


def test_the_check_command_passes_on_the_shipped_files(capsys):
    assert ep.main(["--check"]) == 0
    assert "ArmTrack" in capsys.readouterr().out


def test_the_documented_command_runs_without_runpy_s_warning():
    # docs/protocol.md runs the module with -m: were it imported by the package
    # first, runpy would warn of "unpredictable behaviour" on every run
    import subprocess
    import sys

    command = [sys.executable, "-W", "error::RuntimeWarning", "-m", ep.__name__, "--help"]
    done = subprocess.run(command, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and "--check" in done.stdout, done.stderr
