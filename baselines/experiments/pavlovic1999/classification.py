"""Classification with the SLDS (section 4.1, footnotes 4-5): learn per activity, decode, score.

One SLDS per activity (walk, run) is learned from the training clips, the
models are joined with a block transition matrix, and the Viterbi switch
sequence of a test sequence names the activity of every frame. Test sequences
follow footnote 4: held-out clips in random order, corrupted by noise,
concatenated with B-spline-smoothed transitions (:func:`build_test_sequences`);
the error is footnote 5's, the fraction of all classified frames whose decoded
activity differs from the truth (:func:`classify`).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import make_interp_spline

from baselines.experiments.pavlovic1999.features import (
    assumed_noise,
    feature_transform,
    motion_features,
    parse_features,
)
from baselines.experiments.pavlovic1999.settings import (
    BLEND_FRAMES,
    CLASSIFY_EXTRA_NOISE_DEG,
    CLASSIFY_FEATURES,
    CLASSIFY_INDEX,
    CLASSIFY_SWITCH_PROB,
    CLIPS_PER_SEQUENCE,
    NOISE_STD,
)
from baselines.priors import slds
from baselines.priors.slds_inference import SLDSParams, combine, decode
from baselines.priors.slds_learning import EMResult
from humotion_gym.mocap.motion import Motion

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class TestSequence:
    """One footnote-4 test sequence.

    Attributes:
        angles: ``(T, D)`` the noisy angles the classifier sees.
        clean: ``(T, D)`` the same before the noise.
        truth: ``(T,)`` the activity of every frame.
        clips: The clip ids, in order.
        starts: ``(K,)`` first frame of each clip.
    """

    angles: FloatArray
    clean: FloatArray
    truth: NDArray[np.str_]
    clips: tuple[str, ...]
    starts: NDArray[np.intp]


def _bridge(before: FloatArray, after: FloatArray, blend: int) -> FloatArray:
    """Join two clips, replacing ``blend`` frames each side with a cubic B-spline.

    The spline interpolates four frames before the replaced stretch and four
    after it, so the join is twice continuously differentiable.
    """
    if blend <= 0:
        return np.concatenate([before, after])
    ctx = 4
    if before.shape[0] < blend + ctx or after.shape[0] < blend + ctx:
        return np.concatenate([before, after])
    n_a = before.shape[0]
    knots_t = np.concatenate(
        [np.arange(n_a - blend - ctx, n_a - blend), n_a + blend + np.arange(ctx)]
    ).astype(np.float64)
    knots_y = np.concatenate([before[n_a - blend - ctx : n_a - blend], after[blend : blend + ctx]])
    spline = make_interp_spline(knots_t, knots_y, k=3)
    out = np.concatenate([before, after])
    gap = np.arange(n_a - blend, n_a + blend)
    out[gap] = spline(gap.astype(np.float64))
    return out


def build_test_sequences(
    motions: Sequence[Motion],
    free: ArrayLike,
    rng: np.random.Generator,
    clips_per_sequence: tuple[int, int] = CLIPS_PER_SEQUENCE,
    noise_std: float = NOISE_STD,
    blend_frames: int = BLEND_FRAMES,
    frame_skip: int = 1,
) -> list[TestSequence]:
    """Footnote 4's test sequences: every clip once, in random order and groups.

    The clips are shuffled and cut into groups of ``clips_per_sequence`` (drawn
    uniformly); each group's free angles are concatenated with B-spline
    transitions (:func:`_bridge`) and corrupted by ``N(0, noise_std^2)``. Each
    frame's truth is the label of the clip it came from (a bridged frame
    belongs to the clip on its side of the junction).

    Raises:
        ValueError: If there are no clips.
    """
    if not motions:
        raise ValueError("build_test_sequences: no test clips")
    lo, hi = clips_per_sequence
    if not 1 <= lo <= hi:
        raise ValueError(f"build_test_sequences: bad clips_per_sequence {clips_per_sequence}")
    idx = np.asarray(free, dtype=np.intp)
    order = rng.permutation(len(motions))
    out = []
    pos = 0
    while pos < len(order):
        size = int(rng.integers(lo, hi + 1))
        group = [motions[k] for k in order[pos : pos + size]]
        pos += size
        clean = group[0].params[::frame_skip, idx]
        truth = [np.full(clean.shape[0], group[0].label)]
        starts = [0]
        for m in group[1:]:
            starts.append(clean.shape[0])
            nxt = m.params[::frame_skip, idx]
            clean = _bridge(clean, nxt, blend_frames)
            truth.append(np.full(nxt.shape[0], m.label))
        noisy = clean + noise_std * rng.standard_normal(clean.shape)
        out.append(
            TestSequence(
                noisy,
                clean,
                np.concatenate(truth),
                tuple(m.clip_id for m in group),
                np.array(starts, dtype=np.intp),
            )  # fmt: skip
        )
    return out


def sequence_features(
    sequences: Sequence[TestSequence], features: str, fps: float, free: ArrayLike | None = None
) -> list[TestSequence]:
    """The sequences as the models see them: their noisy angles' features, causally.

    Args:
        sequences: Footnote-4 sequences.
        features: A feature name (:func:`parse_features`).
        fps: Frames per second.
        free: Columns kept first (all when None).
    """
    cols = slice(None) if free is None else np.asarray(free, dtype=np.intp)
    return [
        dataclasses.replace(
            s, angles=feature_transform(s.angles[:, cols], features, fps), clean=s.clean[:, cols]
        )
        for s in sequences
    ]


@dataclass(frozen=True, eq=False)
class ClassificationResult:
    """Footnote 5's score of a classification run.

    Attributes:
        error: Fraction of classified frames whose decoded activity is wrong.
        n_points: Classified frames.
        n_sequences: Test sequences.
        per_label_error: Error among the frames of each true label.
        sequences: The test sequences.
        decoded: ``(T,)`` decoded activity of every sequence.
        switches: ``(T,)`` decoded switch state of every sequence.
        model: The joined model.
        seconds_fit: Time spent learning the models.
        seconds_decode: Time spent decoding.
        costs: Each activity's EM cost per iteration.
    """

    error: float
    n_points: int
    n_sequences: int
    per_label_error: dict[str, float]
    sequences: list[TestSequence]
    decoded: list[NDArray[np.str_]]
    switches: list[NDArray[np.intp]]
    model: SLDSParams
    seconds_fit: float = 0.0
    seconds_decode: float = 0.0
    costs: dict[str, list[float]] = field(default_factory=dict)

    def summary(self) -> dict[str, Any]:
        """The numbers as a JSON-ready dict.

        ``n_states`` is the joined model's: every activity's switch states as
        fitted (EM drops a state no frame uses), not the states per activity asked.
        """
        return {
            "error": round(self.error, 5),
            "n_points": self.n_points,
            "n_sequences": self.n_sequences,
            "per_label_error": {k: round(v, 5) for k, v in self.per_label_error.items()},
            "n_states": self.model.n_states,
            "switch_prob": self.model.switch_prob,
            "seconds_fit": round(self.seconds_fit, 2),
            "seconds_decode": round(self.seconds_decode, 2),
            "em_costs": {k: [round(c, 2) for c in v] for k, v in self.costs.items()},
        }


def with_measurement_noise(fitted: SLDSParams, noise_std: float) -> SLDSParams:
    """The model with ``noise_std^2`` added to the measurement noise ``R``."""
    return fitted.replace(R=fitted.R + noise_std**2 * np.eye(fitted.obs_dim))


def classify(
    model: SLDSParams, sequences: Sequence[TestSequence], noise_std: float = NOISE_STD
) -> tuple[float, list[NDArray[np.str_]], list[NDArray[np.intp]]]:
    """Decode every sequence with the joined model and score it (footnote 5).

    The decoder knows the test noise: ``R`` is increased by ``noise_std^2``.

    Returns:
        The error over all frames, the decoded labels and switch states.
    """
    noisy = with_measurement_noise(model, noise_std)
    paths = decode(noisy, [s.angles for s in sequences])
    labels = [model.state_labels[p] for p in paths]
    wrong = sum(int(np.sum(lab != s.truth)) for lab, s in zip(labels, sequences, strict=True))
    total = sum(s.truth.shape[0] for s in sequences)
    return wrong / max(total, 1), labels, paths


def fit_activity_models(
    motions: Sequence[Motion],
    labels: Sequence[str],
    free: ArrayLike | None,
    rngs: Sequence[np.random.Generator],
    n_states: int = slds.N_STATES,
    n_iter: int = slds.CLASSIFY_N_ITER,
    max_clips: int | None = None,
) -> list[EMResult]:
    """One SLDS per activity label, learned from the clips of that label (section 2.3).

    Args:
        motions: Training clips.
        labels: The activities, in order.
        free: Modelled parameters (:data:`~baselines.priors.slds.SAGITTAL_INDEX` when None).
        rngs: One generator per label (a repeated one is drawn from in turn): it
            picks ``max_clips`` clips where there are more, and seeds EM.
        n_states: Switch states per activity.
        n_iter: EM iterations per activity.
        max_clips: At most this many clips per activity.

    Raises:
        ValueError: Naming a label no clip has.
    """
    out = []
    for label, rng in zip(labels, rngs, strict=True):
        clips = [m for m in motions if m.label == label]
        if not clips:
            raise ValueError(f"no training clip has the label {label!r}")
        if max_clips is not None and len(clips) > max_clips:
            pick = np.sort(rng.choice(len(clips), max_clips, replace=False))
            clips = [clips[k] for k in pick]
        out.append(
            slds.fit_activity(clips, free, rng, n_states=n_states, n_iter=n_iter, label=label)
        )
    return out


def fit_activities(
    motions: Sequence[Motion],
    free: ArrayLike | None = None,
    rng: np.random.Generator | None = None,
    labels: Sequence[str] | None = None,
    n_states: int = slds.N_STATES,
    n_iter: int = slds.CLASSIFY_N_ITER,
    switch_prob: float = slds.SWITCH_PROB,
    max_clips: int | None = None,
) -> tuple[SLDSParams, dict[str, list[float]]]:
    """One model per activity label, joined (section 4.1), with each EM cost history."""
    rng = np.random.default_rng(0) if rng is None else rng
    wanted = sorted({m.label for m in motions}) if labels is None else list(labels)
    fits = fit_activity_models(
        motions, wanted, free, [rng] * len(wanted), n_states, n_iter, max_clips
    )
    costs = {label: fit.costs.tolist() for label, fit in zip(wanted, fits, strict=True)}
    return combine([fit.params for fit in fits], switch_prob), costs


def run_classification(
    train: Sequence[Motion],
    test: Sequence[Motion],
    rng: np.random.Generator,
    free: ArrayLike | None = None,
    labels: Sequence[str] | None = None,
    n_states: int = slds.N_STATES,
    n_iter: int = slds.CLASSIFY_N_ITER,
    switch_prob: float = CLASSIFY_SWITCH_PROB,
    noise_std: float = NOISE_STD,
    max_train_clips: int | None = None,
    clips_per_sequence: tuple[int, int] = CLIPS_PER_SEQUENCE,
    features: str = CLASSIFY_FEATURES,
    extra_noise_deg: float = CLASSIFY_EXTRA_NOISE_DEG,
) -> ClassificationResult:
    """The whole protocol of section 4.1: learn per activity, build test sequences, score.

    Args:
        train: Training clips (their labels name the activities).
        test: Held-out clips; those whose label has no model are left out.
        rng: Generator (initial clustering, test sequence order, noise).
        free: Modelled parameters (:data:`CLASSIFY_INDEX` when None).
        labels: Activities to model (every training label when None).
        n_states: Switch states per activity.
        n_iter: EM iterations per activity.
        switch_prob: Between-activity switching probability per frame.
        noise_std: Noise of the test sequences (rad), known to the decoder.
        max_train_clips: At most this many training clips per activity.
        clips_per_sequence: Clips per test sequence (inclusive range).
        features: What the models see (:func:`parse_features`), training clips
            and test sequences alike.
        extra_noise_deg: Measurement noise (deg) the decoder assumes on top of
            ``noise_std``.

    Raises:
        ValueError: If ``features`` or ``extra_noise_deg`` is malformed, or no
            test clip has a modelled label.
    """
    idx = CLASSIFY_INDEX if free is None else np.asarray(free, dtype=np.intp)
    parse_features(features)
    if not (extra_noise_deg >= 0 and np.isfinite(extra_noise_deg)):
        raise ValueError(f"extra_noise_deg must be finite and >= 0, got {extra_noise_deg}")
    start = time.perf_counter()
    fps = float(train[0].fps) if train else 30.0
    model, costs = fit_activities(
        [motion_features(m, features) for m in train], idx, rng, labels, n_states, n_iter,
        switch_prob, max_train_clips,
    )  # fmt: skip
    fitted_s = time.perf_counter() - start
    known = set(model.state_labels.tolist())
    test_clips = [m for m in test if m.label in known]
    if not test_clips:
        raise ValueError(f"no test clip has one of the modelled labels {sorted(known)}")
    sequences = build_test_sequences(
        test_clips, idx, rng, clips_per_sequence=clips_per_sequence, noise_std=noise_std
    )
    sequences = sequence_features(sequences, features, fps)
    start = time.perf_counter()
    error, decoded, switches = classify(
        model, sequences, assumed_noise(features, noise_std, extra_noise_deg, fps)
    )
    decode_s = time.perf_counter() - start
    truth = np.concatenate([s.truth for s in sequences])
    dec = np.concatenate(decoded)
    per_label = {lab: float(np.mean(dec[truth == lab] != lab)) for lab in sorted(set(truth))}
    return ClassificationResult(
        error, int(truth.shape[0]), len(sequences), per_label, sequences, decoded, switches,
        model, fitted_s, decode_s, costs,
    )  # fmt: skip
