"""Scoring a grid of classifier settings on shared test sequences, in forked processes.

Each activity's SLDS is fitted once per parameter subset and features; the
switch probability and the extra assumed noise only change the decoding, so
they cost a decode, not a fit (:func:`score_fits`). :func:`run_jobs` runs many
such scorings (cross-validation folds, train/test splits) in processes.
"""

from __future__ import annotations

import multiprocessing
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from baselines.experiments.pavlovic1999.classification import (
    TestSequence,
    build_test_sequences,
    classify,
    fit_activity_models,
    sequence_features,
)
from baselines.experiments.pavlovic1999.features import (
    assumed_noise,
    motion_features,
    parse_features,
)
from baselines.experiments.pavlovic1999.settings import (
    CLASSIFY_LABELS,
    CLIPS_PER_SEQUENCE,
    NOISE_STD,
    param_indices,
)
from baselines.priors import slds
from baselines.priors.slds_inference import combine
from humotion_gym.body import PARAM_NAMES
from humotion_gym.mocap.motion import Motion

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class SettingScores:
    """Misclassified frames of a grid of settings on one set of test sequences.

    Attributes:
        labels: The activities.
        wrong: ``(P, W, L)`` misclassified frames per parameter subset, switch
            probability and true label.
        frames: ``(L,)`` frames of each true label.
        n_sequences: Test sequences.
        n_clips: Test clips.
    """

    labels: tuple[str, ...]
    wrong: NDArray[np.int64]
    frames: NDArray[np.int64]
    n_sequences: int
    n_clips: int

    @property
    def error(self) -> FloatArray:
        """``(P, W)`` footnote 5's error."""
        return self.wrong.sum(axis=-1) / max(int(self.frames.sum()), 1)

    @property
    def per_label_error(self) -> FloatArray:
        """``(P, W, L)`` error among the frames of each true label (NaN: no frame)."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(self.frames > 0, self.wrong / np.maximum(self.frames, 1), np.nan)


def _test_sequences_all_params(
    test: Sequence[Motion], rng: np.random.Generator, noise_std: float,
    clips_per_sequence: tuple[int, int],
) -> list[TestSequence]:  # fmt: skip
    """Footnote-4 sequences of all 25 parameters, to be sliced per subset.

    Noise is drawn for every parameter, so a subset's sequences do not depend
    on which other subsets are scored with it.
    """
    return build_test_sequences(
        test, np.arange(len(PARAM_NAMES)), rng, clips_per_sequence=clips_per_sequence,
        noise_std=noise_std,
    )  # fmt: skip


def score_fits(
    train: Sequence[Motion],
    tests: Sequence[Sequence[Motion]],
    fits: Sequence[tuple[tuple[str, ...], str]],
    decodes: Sequence[tuple[float, float]],
    seed: int,
    labels: Sequence[str] = CLASSIFY_LABELS,
    n_states: int = slds.N_STATES,
    n_iter: int = slds.CLASSIFY_N_ITER,
    noise_std: float = NOISE_STD,
    clips_per_sequence: tuple[int, int] = CLIPS_PER_SEQUENCE,
) -> list[SettingScores]:
    """Learn once per fit, decode every test set at every decode option.

    EM is seeded by ``[seed, 1]`` for every fit; each test set's footnote-4
    sequences are drawn once (seeded by ``[seed, 2, k]``) and shared by every
    setting, their features computed causally from their noisy angles. Clips
    whose label is not in ``labels`` are dropped.

    Args:
        train: Training clips with the activity labels.
        tests: Test sets.
        fits: ``(params, features)`` pairs, one fit of every activity each.
        decodes: ``(switch_prob, extra_noise_deg)`` pairs, one decode each.
        seed: Seed of the fits and test sequences.
        labels: The activities.
        n_states: Switch states per activity.
        n_iter: EM iterations per activity.
        noise_std: Test noise (rad) on the angles, known to the decoder.
        clips_per_sequence: Clips per test sequence (inclusive range).

    Returns:
        One :class:`SettingScores` per test set, ``wrong`` ``(len(fits),
        len(decodes), L)``.

    Raises:
        ValueError: If a test set has no clip of the labels, a feature name is
            unknown or no training clip has a label.
    """
    labels = tuple(labels)
    for _, feat in fits:
        parse_features(feat)
    test_sets = [[m for m in t if m.label in labels] for t in tests]
    for k, t in enumerate(test_sets):
        if not t:
            raise ValueError(f"score_fits: test set {k} has no clip labelled {labels}")
    fps = float(train[0].fps) if train else 30.0
    seqs = [
        _test_sequences_all_params(t, np.random.default_rng([seed, 2, k]), noise_std,
                                   clips_per_sequence)
        for k, t in enumerate(test_sets)
    ]  # fmt: skip
    truths = [np.concatenate([s.truth for s in seq_set]) for seq_set in seqs]
    wrong = [np.zeros((len(fits), len(decodes), len(labels)), dtype=np.int64) for _ in tests]
    for p, (names, feat) in enumerate(fits):
        idx = param_indices(names)
        # every label's EM starts from the same seed, whatever the other fits
        rngs = [np.random.default_rng([seed, 1]) for _ in labels]
        feat_train = [motion_features(m, feat) for m in train]
        models = [r.params for r in fit_activity_models(feat_train, labels, idx, rngs,
                                                        n_states, n_iter)]  # fmt: skip
        for k, seq_set in enumerate(seqs):
            sliced = sequence_features(seq_set, feat, fps, idx)
            for w, (prob, extra) in enumerate(decodes):
                noise = assumed_noise(feat, noise_std, extra, fps)
                _, decoded, _ = classify(combine(models, prob), sliced, noise)
                bad = np.concatenate(decoded) != truths[k]
                wrong[k][p, w] = [np.sum(bad & (truths[k] == lab)) for lab in labels]
    frames = [np.array([np.sum(t == lab) for lab in labels], np.int64) for t in truths]
    return [
        SettingScores(labels, wrong[k], frames[k], len(seq_set), len(test_sets[k]))
        for k, seq_set in enumerate(seqs)
    ]


# Clips of a scoring run, set before forking its worker processes (each job
# names its clips by index, so the clips are not pickled once per job).
_POOL_MOTIONS: list[Motion] = []


def _set_pool_motions(motions: list[Motion]) -> None:
    global _POOL_MOTIONS
    _POOL_MOTIONS = motions


#: One scoring job: ``(train ids, [test ids per test set], fits, decodes, seed,
#: score_fits keywords)``.
ScoreJob = tuple[
    list[int], list[list[int]], list[tuple[tuple[str, ...], str]], list[tuple[float, float]],
    int, dict[str, Any],
]  # fmt: skip


def _score_job(
    train_ids: list[int], test_ids: list[list[int]], fits: list[tuple[tuple[str, ...], str]],
    decodes: list[tuple[float, float]], seed: int, options: dict[str, Any],
) -> list[SettingScores]:  # fmt: skip
    train = [_POOL_MOTIONS[i] for i in train_ids]
    tests = [[_POOL_MOTIONS[i] for i in ids] for ids in test_ids]
    return score_fits(train, tests, fits, decodes, seed, **options)


def run_jobs(
    motions: list[Motion],
    jobs_args: Sequence[ScoreJob],
    jobs: int,
    log: Callable[[str], None] | None = None,
    names: Sequence[str] | None = None,
) -> list[list[SettingScores]]:
    """:func:`score_fits` of each job in ``jobs`` forked processes (the same results for any).

    Args:
        motions: The clips the jobs' ids index.
        jobs_args: The jobs (:data:`ScoreJob`).
        jobs: Processes (1: in this one).
        log: Called after each job with ``"<name>: <seconds> s"`` (None: silent).
        names: The jobs' names in the log (``"fit k/n"`` when None).
    """
    start = time.perf_counter()
    total = len(jobs_args)
    names = [f"fit {k + 1}/{total}" for k in range(total)] if names is None else list(names)
    out: list[list[SettingScores]] = []

    def done(result: list[SettingScores]) -> None:
        out.append(result)
        if log is not None:
            log(f"{names[len(out) - 1]}: {time.perf_counter() - start:.0f} s")

    _set_pool_motions(motions)
    try:
        if jobs == 1:
            for a in jobs_args:
                done(_score_job(*a))
        else:
            ctx = multiprocessing.get_context("fork")
            with ProcessPoolExecutor(jobs, ctx, _set_pool_motions, (motions,)) as pool:
                for fut in [pool.submit(_score_job, *a) for a in jobs_args]:
                    done(fut.result())
    finally:
        _set_pool_motions([])
    return out
