"""Choosing the classifier's settings by leave-one-group-out CV on the training split.

A group is a Bandai-Namco style ("style held out, same performers") or a
training person ("person held out"); every fold trains on all other training
clips and decodes footnote-4 sequences of the held-out group's clips. A clip
of a test person is refused before any fold runs (:func:`check_training_only`).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from baselines.experiments.pavlovic1999.data import activity_clips
from baselines.experiments.pavlovic1999.features import parse_features
from baselines.experiments.pavlovic1999.scoring import ScoreJob, SettingScores, run_jobs
from baselines.experiments.pavlovic1999.settings import (
    CANDIDATE_PARAMS,
    CANDIDATE_SWITCH_PROBS,
    CLASSIFY_LABELS,
    CV_CRITERIA,
    NOISE_STD,
    ClassifierSetting,
    param_indices,
)
from baselines.priors import slds
from humotion_gym.mocap.library import TEST_SUBJECTS
from humotion_gym.mocap.motion import Motion

FloatArray = NDArray[np.float64]


def check_training_only(motions: Sequence[Motion], what: str = "motions") -> None:
    """Refuse any clip of a held-out test person (``library.TEST_SUBJECTS``).

    Raises:
        ValueError: Naming the first such clip and its subject.
    """
    for m in motions:
        if m.subject in TEST_SUBJECTS:
            raise ValueError(
                f"{what}: clip {m.clip_id!r} is of the test subject {m.subject!r}; settings "
                "must be chosen on the training split only (MotionLibrary.split('train'))"
            )


def cv_groups(motions: Sequence[Motion], every_person: bool = False) -> list[str | None]:
    """The cross-validation group of every clip (None: in every fold's training data).

    A Bandai-Namco style (subject ``"bandai-2/masculine"``...) is a group: the
    same actors perform every style, so holding one out is "style held out,
    same performers". Any other subject is a group when it has clips of two or
    more activities (a held-out person); a subject with one activity only
    (CMU subject 7's walks) always trains, unless ``every_person``: then every
    non-Bandai subject is its own group (leave-one-person-out: a fold of a
    person who only walks scores how often a new person's walking is read as
    running, the error the test persons show).
    """
    labels: dict[str, set[str]] = {}
    for m in motions:
        labels.setdefault(m.subject, set()).add(m.label)
    out: list[str | None] = []
    for m in motions:
        bandai = m.dataset.startswith("bandai")
        person = every_person or len(labels[m.subject]) > 1
        out.append(m.subject if bandai or person else None)
    return out


def held_out_groups(motions: Sequence[Motion], person_folds: bool = True) -> list[str]:
    """The groups the CV holds out in turn (:func:`cv_groups` of the classified activities' clips).

    Args:
        motions: Training clips (any labels; the others are ignored).
        person_folds: Every training person outside Bandai-Namco is a group.

    Raises:
        ValueError: If there are fewer than two, saying what the clips lack.
    """
    clips = activity_clips(motions)
    held = sorted({g for g in cv_groups(clips, every_person=person_folds) if g is not None})
    if len(held) < 2:
        person = "a person" if person_folds else "a person with clips of both activities"
        found = f"only one, {held[0]}" if held else "none"
        raise ValueError(
            f"need two CV groups to hold out in turn, each a Bandai-Namco style or {person}; the "
            f"{len(clips)} {' and '.join(CLASSIFY_LABELS)} clips of training persons hold {found}"
        )
    return held


def group_kind(group: str) -> str:
    """How a held-out group relates to the training data, in words."""
    if group.startswith("bandai"):
        return "style held out, same performers"
    return "person held out"


def _pooled(fold_scores: Sequence[SettingScores]) -> FloatArray:
    """``(K,)`` misclassified frames over all the folds' frames, per setting."""
    wrong = np.sum([sc.wrong.sum(axis=-1).reshape(-1) for sc in fold_scores], axis=0)
    return wrong / max(int(sum(sc.frames.sum() for sc in fold_scores)), 1)


def criterion_scores(
    groups: Sequence[str], fold_scores: Sequence[SettingScores], criterion: str
) -> tuple[FloatArray, dict[str, FloatArray]]:
    """The selection score of every setting and the pooled error of each kind of fold.

    Args:
        groups: The held-out group of each fold.
        fold_scores: The folds' scores (the same settings in each).
        criterion: ``"frames"``: misclassified frames over all folds' frames;
            ``"kinds"``: the mean over the kinds of fold (:func:`group_kind`)
            of each kind's pooled error.

    Returns:
        ``(K,)`` scores (lower is better) and ``{kind: (K,) pooled error}``.

    Raises:
        ValueError: If ``criterion`` is not one of :data:`CV_CRITERIA`.
    """
    if criterion not in CV_CRITERIA:
        raise ValueError(f"criterion: unknown {criterion!r}; choose from {CV_CRITERIA}")
    per_kind = {
        kind: _pooled([sc for g, sc in zip(groups, fold_scores, strict=True)
                       if group_kind(g) == kind])
        for kind in sorted({group_kind(g) for g in groups})
    }  # fmt: skip
    if criterion == "frames":
        return _pooled(fold_scores), per_kind
    return np.mean(list(per_kind.values()), axis=0), per_kind


@dataclass(frozen=True, eq=False)
class SelectionResult:
    """Leave-one-group-out cross-validation of the classifier's settings.

    Attributes:
        settings: The candidates, in tie-breaking order (simplest first).
        groups: The held-out groups, one fold each.
        fold_scores: Each fold's :class:`SettingScores` (settings flattened to
            ``fits x decodes``).
        cv_error: ``(K,)`` misclassified frames over all folds' frames, per setting.
        mean_fold_error: ``(K,)`` unweighted mean of the folds' errors.
        per_label_error: ``(K, L)`` pooled error per true label.
        chosen: Index of the chosen setting (lowest ``score``, the first on ties).
        n_train_clips: Clips cross-validated over.
        seconds: Wall time.
        criterion: How the settings were scored (:data:`CV_CRITERIA`).
        score: ``(K,)`` the criterion's value per setting (None: ``cv_error``).
        kind_error: ``{kind: (K,)}`` pooled error of each kind of fold.
    """

    settings: list[ClassifierSetting]
    groups: list[str]
    fold_scores: list[SettingScores]
    cv_error: FloatArray
    mean_fold_error: FloatArray
    per_label_error: FloatArray
    chosen: int
    n_train_clips: int
    seconds: float = 0.0
    criterion: str = "frames"
    score: FloatArray | None = None
    kind_error: dict[str, FloatArray] = field(default_factory=dict)

    @property
    def best(self) -> ClassifierSetting:
        """The chosen setting."""
        return self.settings[self.chosen]

    @property
    def scores(self) -> FloatArray:
        """``(K,)`` the criterion's value per setting."""
        return self.cv_error if self.score is None else self.score

    def summary(self) -> dict[str, Any]:
        """The numbers as a JSON-ready dict."""
        labels = self.fold_scores[0].labels
        n_probs = len({s.switch_prob for s in self.settings})
        kinds = {k: np.round(v, 5).tolist() for k, v in self.kind_error.items()}
        return {
            "chosen": {"params": list(self.best.params), "switch_prob": self.best.switch_prob,
                       "name": self.best.name, "features": self.best.features,
                       "extra_noise_deg": self.best.extra_noise_deg,
                       "cv_error": round(float(self.cv_error[self.chosen]), 5),
                       "score": round(float(self.scores[self.chosen]), 5)},
            "criterion": self.criterion,
            "settings": [
                {"name": s.name, "params": list(s.params), "switch_prob": s.switch_prob,
                 "features": s.features, "extra_noise_deg": s.extra_noise_deg,
                 "cv_error": round(float(e), 5), "score": round(float(sc), 5),
                 "mean_fold_error": round(float(f), 5),
                 "kind_error": {k: v[i] for k, v in kinds.items()},
                 "per_label_error": dict(zip(labels, np.round(pl, 5).tolist(), strict=True))}
                for i, (s, e, sc, f, pl) in enumerate(zip(
                    self.settings, self.cv_error, self.scores, self.mean_fold_error,
                    self.per_label_error, strict=True))
            ],
            "folds": [
                {"group": g, "kind": group_kind(g), "frames": int(sc.frames.sum()),
                 "sequences": sc.n_sequences, "clips": sc.n_clips,
                 "error": {s.label(): round(float(e), 5) for s, e in
                           zip(self.settings, sc.error.reshape(-1), strict=True)}}
                for g, sc in zip(self.groups, self.fold_scores, strict=True)
            ],
            "n_train_clips": self.n_train_clips,
            "cv_frames": int(sum(sc.frames.sum() for sc in self.fold_scores)),
            "n_switch_probs": n_probs,
            "seconds": round(self.seconds, 1),
        }  # fmt: skip

    def table(self) -> str:
        """The candidates and their cross-validation errors, as text."""
        labels = self.fold_scores[0].labels
        frames = int(sum(sc.frames.sum() for sc in self.fold_scores))
        seqs = sum(sc.n_sequences for sc in self.fold_scores)
        kinds = list(self.kind_error)
        short = {"style held out, same performers": "styles", "person held out": "persons"}
        head = (f"{'params':16s} {'features':11s} {'switch':>7s} {'+noise':>6s} {'score':>7s} "
                f"{'CV error':>9s} {'fold mean':>9s} "
                + " ".join(f"{short.get(k, k):>8s}" for k in kinds) + " "
                + " ".join(f"{lab:>7s}" for lab in labels))  # fmt: skip
        lines = [
            f"leave-one-group-out CV on {self.n_train_clips} training clips, {len(self.groups)} "
            f"folds, {frames} frames in {seqs} sequences (no test person); criterion "
            f"{self.criterion!r}:",
            head,
            "-" * len(head),
        ]
        for k, (s, e, f, pl) in enumerate(
            zip(self.settings, self.cv_error, self.mean_fold_error, self.per_label_error,
                strict=True)
        ):  # fmt: skip
            mark = "  <- chosen" if k == self.chosen else ""
            lines.append(
                f"{s.name:16s} {s.features:11s} {s.switch_prob:7.0e} {s.extra_noise_deg:6g} "
                f"{100 * self.scores[k]:6.2f}% {100 * e:8.2f}% {100 * f:8.2f}% "
                + " ".join(f"{100 * self.kind_error[kd][k]:7.2f}%" for kd in kinds)
                + " "
                + " ".join(f"{100 * v:6.2f}%" for v in pl)
                + mark
            )
        lines.append("folds: " + ", ".join(
            f"{g} ({int(sc.frames.sum())} frames)" for g, sc in zip(self.groups, self.fold_scores,
                                                                    strict=True)))  # fmt: skip
        return "\n".join(lines)


def _candidate_grid(
    param_sets: dict[str, Sequence[str]],
    switch_probs: Sequence[float],
    features: Sequence[str],
    extra_noise_degs: Sequence[float],
) -> tuple[list[tuple[tuple[str, ...], str]], list[str], list[tuple[float, float]]]:
    """The fits (simplest subset first), their subsets' names, and the decodes, checked."""
    what = "select_classifier_settings"
    if not param_sets or not switch_probs or not features or not extra_noise_degs:
        raise ValueError(
            f"{what}: param_sets, switch_probs, features and extra_noise_degs must be non-empty"
        )
    for name, names in param_sets.items():
        param_indices(names)
        if not names:
            raise ValueError(f"{what}: param_sets[{name!r}] is empty")
    feats = list(dict.fromkeys(features))
    for feat in feats:
        parse_features(feat)
    probs = [float(p) for p in switch_probs]
    if any(not 0.0 < p < 1.0 for p in probs):
        raise ValueError(f"{what}: switch_probs must be in (0, 1), got {probs}")
    extras = [float(n) for n in extra_noise_degs]
    if any(not (n >= 0.0 and np.isfinite(n)) for n in extras):
        raise ValueError(f"{what}: extra_noise_degs must be finite and >= 0, got {extras}")
    order = list(param_sets)
    names_sorted = sorted(param_sets, key=lambda n: (len(param_sets[n]), order.index(n)))
    fits = [(tuple(param_sets[n]), f) for n in names_sorted for f in feats]
    fit_names = [n for n in names_sorted for _ in feats]
    return fits, fit_names, [(p, n) for p in probs for n in extras]


def select_classifier_settings(
    train_motions: Sequence[Motion],
    rng: np.random.Generator,
    param_sets: dict[str, Sequence[str]] | None = None,
    switch_probs: Sequence[float] = CANDIDATE_SWITCH_PROBS,
    n_states: int = slds.N_STATES,
    n_iter: int = slds.CLASSIFY_N_ITER,
    noise_std: float = NOISE_STD,
    jobs: int = 1,
    log: Callable[[str], None] | None = None,
    features: Sequence[str] = ("angles",),
    extra_noise_degs: Sequence[float] = (0.0,),
    person_folds: bool = True,
    criterion: str = "kinds",
) -> SelectionResult:
    """Choose the classifier's setting by leave-one-group-out CV on the training split.

    Only training clips are used (a clip of a test subject raises). The clips
    of :data:`CLASSIFY_LABELS` (with :data:`LABEL_ALIASES` folded in) are
    grouped by :func:`cv_groups` (with ``person_folds``, every training person
    outside the Bandai-Namco sets is a fold: leave-one-person-out); every fold
    trains on all other clips and decodes footnote-4 sequences of the held-out
    group's clips (:func:`score_fits`: one fit per subset, features and fold;
    the switch probability and the extra assumed noise varied at decode time).
    The chosen setting has the lowest ``criterion`` (:func:`criterion_scores`),
    ties going to the simpler one: fewer parameters first, then the earlier
    features, switch probability and extra noise in the order given.

    Args:
        train_motions: Training clips (any labels; the others are ignored).
        rng: Generator: each fold's seed is drawn from it.
        param_sets: Named parameter subsets (:data:`CANDIDATE_PARAMS` when None).
        switch_probs: Candidate switching probabilities.
        n_states: Switch states per activity.
        n_iter: EM iterations per activity.
        noise_std: Test noise (rad).
        jobs: Folds run in this many processes (the result does not depend on it).
        log: Called with a line of progress after each fold (None: silent).
        features: Candidate features (:func:`parse_features`).
        extra_noise_degs: Candidate extra assumed noise (deg, >= 0).
        person_folds: Hold out every training person (outside Bandai-Namco) as a fold.
        criterion: ``"kinds"`` or ``"frames"`` (:data:`CV_CRITERIA`).

    Raises:
        ValueError: If a clip is of a test subject, if there are fewer than two
            groups, or if a candidate or the criterion is malformed.
    """
    what = "select_classifier_settings"
    check_training_only(train_motions, f"{what}: train_motions")
    param_sets = dict(CANDIDATE_PARAMS if param_sets is None else param_sets)
    fits, fit_names, decodes = _candidate_grid(param_sets, switch_probs, features,
                                               extra_noise_degs)  # fmt: skip
    if criterion not in CV_CRITERIA:
        raise ValueError(f"{what}: criterion must be one of {CV_CRITERIA}, got {criterion!r}")
    if jobs < 1:
        raise ValueError(f"{what}: jobs must be >= 1, got {jobs}")
    motions = activity_clips(train_motions)
    groups = cv_groups(motions, every_person=person_folds)
    try:
        held = held_out_groups(motions, person_folds)
    except ValueError as exc:
        raise ValueError(f"{what}: {exc}") from None
    seeds = rng.integers(0, 2**62, size=len(held))
    options = {"n_states": n_states, "n_iter": n_iter, "noise_std": noise_std}
    folds: list[ScoreJob] = [
        ([i for i, g in enumerate(groups) if g != h], [[i for i, g in enumerate(groups) if g == h]],
         fits, decodes, int(s), options)
        for h, s in zip(held, seeds, strict=True)
    ]  # fmt: skip
    start = time.perf_counter()
    names = [f"fold {k + 1}/{len(held)} {h}" for k, h in enumerate(held)]
    scores = [r[0] for r in run_jobs(motions, folds, jobs, log, names)]
    settings = [
        ClassifierSetting(params, prob, fit_names[p], feat, extra)
        for p, (params, feat) in enumerate(fits) for prob, extra in decodes
    ]  # fmt: skip
    wrong = np.sum([sc.wrong for sc in scores], axis=0).reshape(len(settings), -1)
    frames = np.sum([sc.frames for sc in scores], axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        per_label = np.where(frames > 0, wrong / np.maximum(frames, 1), np.nan)
    fold_mean = np.mean([sc.error.reshape(-1) for sc in scores], axis=0)
    score, per_kind = criterion_scores(held, scores, criterion)
    chosen = int(np.argmin(score))  # the first minimum: the simplest tied setting
    return SelectionResult(
        settings, held, scores, _pooled(scores), fold_mean, per_label, chosen, len(motions),
        time.perf_counter() - start, criterion, score, per_kind,
    )  # fmt: skip
