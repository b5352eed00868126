"""The classifier's error, at fixed settings, per held-out style and per held-out person.

Nothing here chooses a setting: :func:`evaluate_splits` scores given ones
(by default the CV-chosen and the old fixed settings) on several train/test
splits, each training set fitted once per parameter subset and features.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from baselines.experiments.pavlovic1999.data import activity_clips
from baselines.experiments.pavlovic1999.scoring import ScoreJob, SettingScores, run_jobs
from baselines.experiments.pavlovic1999.settings import (
    CLASSIFY_LABELS,
    NOISE_STD,
    ClassifierSetting,
    default_settings,
)
from baselines.priors import slds
from humotion_gym.mocap.library import TEST_SUBJECTS
from humotion_gym.mocap.motion import Motion


@dataclass(frozen=True)
class SplitRow:
    """The classification error of one setting on one train/test split.

    Attributes:
        split: The held-out part (``"bandai-2/masculine"``, ``"cmu-02 + cmu-03"``...).
        kind: ``"style held out, same performers"`` or ``"person held out"``.
        setting_name: ``"CV-chosen"`` or ``"old fixed"``...
        setting: The setting.
        train_clips: Training clips.
        test_clips: Test clips.
        frames: Classified frames.
        sequences: Footnote-4 test sequences.
        error: Footnote 5's error.
        per_label_error: Error among the frames of each true label.
        per_label_frames: Frames of each true label.
    """

    split: str
    kind: str
    setting_name: str
    setting: ClassifierSetting
    train_clips: int
    test_clips: int
    frames: int
    sequences: int
    error: float
    per_label_error: dict[str, float]
    per_label_frames: dict[str, int]

    def summary(self) -> dict[str, Any]:
        """The row as a JSON-ready dict."""
        return {
            "split": self.split, "kind": self.kind, "setting": self.setting_name,
            "params": list(self.setting.params), "switch_prob": self.setting.switch_prob,
            "features": self.setting.features, "extra_noise_deg": self.setting.extra_noise_deg,
            "train_clips": self.train_clips, "test_clips": self.test_clips,
            "frames": self.frames, "sequences": self.sequences, "error": round(self.error, 5),
            "per_label_error": {k: round(v, 5) for k, v in self.per_label_error.items()},
            "per_label_frames": self.per_label_frames,
        }  # fmt: skip


#: A split plan: the held-out parts' names, their kind, the training clips'
#: ids and each held-out part's clip ids.
_Plan = tuple[list[str], str, list[int], list[list[int]]]


def _held_out(train_ids: list[int], clips: Sequence[Motion], subject: str) -> tuple[list[int], ...]:
    """The training clips of ``subject`` and the other training clips."""
    held = [i for i in train_ids if clips[i].subject == subject]
    return held, [i for i in train_ids if clips[i].subject != subject]


def _split_plans(
    clips: Sequence[Motion], style_dataset: str, training_persons: bool
) -> list[_Plan]:
    """The splits of :func:`evaluate_splits`, in the order their seeds are drawn."""
    is_test = np.array([m.subject in TEST_SUBJECTS for m in clips], dtype=bool)
    train_ids = np.flatnonzero(~is_test).tolist()
    styles = sorted({clips[i].subject for i in train_ids if clips[i].dataset == style_dataset})
    persons = sorted({m.subject for m in clips if m.subject in TEST_SUBJECTS})
    if not styles and not persons:
        raise ValueError(
            f"nothing to hold out: no {style_dataset} style among the training persons' "
            f"{' and '.join(CLASSIFY_LABELS)} clips and no clip of a test person "
            f"({', '.join(sorted(TEST_SUBJECTS))})"
        )
    plans: list[_Plan] = []
    for style in styles:
        held, rest = _held_out(train_ids, clips, style)
        plans.append(([style], "style held out, same performers", rest, [held]))
    if persons:
        names = [" + ".join(persons)] + (persons if len(persons) > 1 else [])
        tests = [np.flatnonzero(is_test).tolist()] + (
            [[i for i, m in enumerate(clips) if m.subject == p] for p in persons]
            if len(persons) > 1 else []
        )  # fmt: skip
        plans.append((names, "person held out", train_ids, tests))
    if training_persons:  # after the others: their seeds stay those drawn without them
        for person in sorted({clips[i].subject for i in train_ids
                              if not clips[i].dataset.startswith("bandai")}):  # fmt: skip
            held, rest = _held_out(train_ids, clips, person)
            plans.append(([person], "training person held out", rest, [held]))
    return plans


def check_splits(motions: Sequence[Motion], style_dataset: str = "bandai-2") -> None:
    """Refuse motions with no split for :func:`evaluate_splits`, before any fit.

    Raises:
        ValueError: If there is neither a style nor a test person to hold out.
    """
    _split_plans(activity_clips(motions), style_dataset, training_persons=False)


def _setting_row(
    split: str, kind: str, name: str, setting: ClassifierSetting, train_clips: int,
    test_clips: int, sc: SettingScores, p: int, w: int,
) -> SplitRow:  # fmt: skip
    """The row of fit ``p`` and decode ``w`` of one held-out part's scores."""
    per = sc.per_label_error[p, w]
    return SplitRow(
        split, kind, name, setting, train_clips, test_clips, int(sc.frames.sum()),
        sc.n_sequences, float(sc.error[p, w]),
        {lab: float(v) for lab, v, f in zip(sc.labels, per, sc.frames, strict=True) if f > 0},
        {lab: int(f) for lab, f in zip(sc.labels, sc.frames, strict=True)},
    )  # fmt: skip


def evaluate_splits(
    motions: Sequence[Motion],
    rng: np.random.Generator,
    settings: dict[str, ClassifierSetting] | None = None,
    style_dataset: str = "bandai-2",
    n_states: int = slds.N_STATES,
    n_iter: int = slds.CLASSIFY_N_ITER,
    noise_std: float = NOISE_STD,
    jobs: int = 1,
    log: Callable[[str], None] | None = None,
    training_persons: bool = False,
) -> list[SplitRow]:
    """The classification error of fixed settings on several train/test splits.

    The settings are given (by default :func:`default_settings`: the
    CV-chosen ones and the old fixed ones); nothing here chooses them.

    * One split per style of ``style_dataset`` in the training split: train on
      every other training clip, test on the style ("style held out, same
      performers").
    * The held-out persons: train on the whole training split, test on the
      test persons' clips (``library.TEST_SUBJECTS``) together and each alone
      ("person held out").
    * With ``training_persons``: one split per training person outside the
      Bandai-Namco sets (CMU subjects 5 and 7 in the shared data, who only
      walk): train on every other training clip, test on that person ("training
      person held out", the leave-one-person-out folds of the CV).

    Only :data:`CLASSIFY_LABELS` (with :data:`LABEL_ALIASES`) are used. Each
    training set is fitted once per parameter subset; its seed is drawn from
    ``rng``.

    Raises:
        ValueError: If there is neither a style nor a test person to hold out.
    """
    settings = default_settings() if settings is None else dict(settings)
    clips = activity_clips(motions)
    try:
        plans = _split_plans(clips, style_dataset, training_persons)
    except ValueError as exc:
        raise ValueError(f"evaluate_splits: {exc}") from None
    fits = list(dict.fromkeys(s.fit_key for s in settings.values()))
    decodes = list(dict.fromkeys(s.decode_key for s in settings.values()))
    options = {"n_states": n_states, "n_iter": n_iter, "noise_std": noise_std}
    seeds = rng.integers(0, 2**62, size=len(plans))
    args: list[ScoreJob] = [
        (tr, te, fits, decodes, int(s), options)
        for (_, _, tr, te), s in zip(plans, seeds, strict=True)
    ]
    results = run_jobs(clips, args, jobs, log)
    rows = []
    for (names, kind, tr, tests), scores in zip(plans, results, strict=True):
        for split, ids, sc in zip(names, tests, scores, strict=True):
            for name, st in settings.items():
                p, w = fits.index(st.fit_key), decodes.index(st.decode_key)
                rows.append(_setting_row(split, kind, name, st, len(tr), len(ids), sc, p, w))
    return rows


def splits_table(rows: Sequence[SplitRow]) -> str:
    """The per-split errors as text."""
    head = (f"{'held out':26s} {'setting':10s} {'params':15s} {'features':11s} {'switch':>6s} "
            f"{'+noise':>6s} {'train':>5s} {'test':>4s} {'frames':>6s} {'seqs':>4s} {'error':>7s}"
            "  per label")  # fmt: skip
    lines = [head, "-" * (len(head) + 20)]
    kind = None
    for r in rows:
        if r.kind != kind:
            kind = r.kind
            lines.append(f"[{kind}]")
        per = ", ".join(
            f"{lab} {100 * e:.2f}% of {r.per_label_frames[lab]}"
            for lab, e in r.per_label_error.items()
        )
        lines.append(
            f"{r.split:26s} {r.setting_name:10s} {r.setting.name:15s} {r.setting.features:11s} "
            f"{r.setting.switch_prob:6.0e} {r.setting.extra_noise_deg:6g} {r.train_clips:5d} "
            f"{r.test_clips:4d} {r.frames:6d} {r.sequences:4d} "
            f"{100 * r.error:6.2f}%  {per}"
        )
    return "\n".join(lines)
