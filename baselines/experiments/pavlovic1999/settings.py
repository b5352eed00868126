"""The activity classifier's settings: the protocol's constants, the candidates, the choices.

The chosen values (:data:`CLASSIFY_PARAMS`, :data:`CLASSIFY_SWITCH_PROB`,
:data:`CLASSIFY_FEATURES`, :data:`CLASSIFY_EXTRA_NOISE_DEG`) come from
leave-one-group-out cross-validation on the training split only
(:func:`~baselines.experiments.pavlovic1999.cross_validation.select_classifier_settings`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from baselines.experiments.pavlovic1999.features import parse_features
from humotion_gym.body import PARAM_INDEX, SAGITTAL_PARAMS

#: Standard deviation of the noise added to the test sequences (rad), about 2 deg.
NOISE_STD = float(np.radians(2.0))
#: Activities the classifier tells apart.
CLASSIFY_LABELS: tuple[str, ...] = ("walk", "run")
#: Labels folded into them: Bandai-Namco set 1's ``dash`` (a sprint, with a
#: flight phase like every run) is running.
LABEL_ALIASES: dict[str, str] = {"dash": "run"}
#: Leg angles: the sagittal hip and knee angles.
LEG_PARAMS: tuple[str, ...] = ("r_hip_x", "r_knee", "l_hip_x", "l_knee")
#: Candidate parameter subsets of ``select_classifier_settings``.
CANDIDATE_PARAMS: dict[str, tuple[str, ...]] = {
    "legs": LEG_PARAMS,
    "legs+shoulders": (*LEG_PARAMS, "r_shoulder_x", "l_shoulder_x"),
    "sagittal": SAGITTAL_PARAMS,
}
#: Candidate between-activity switching probabilities per frame.
CANDIDATE_SWITCH_PROBS: tuple[float, ...] = (1e-2, 1e-3, 1e-4, 1e-5)
#: The settings used before they were chosen by cross-validation: picked after
#: looking at held-out results (kept only to compare with, never as a default).
OLD_CLASSIFY_PARAMS: tuple[str, ...] = LEG_PARAMS
OLD_CLASSIFY_SWITCH_PROB = 1e-3
#: Angles the classifier sees: the legs and the shoulders' swing, chosen by
#: ``humotion-gym slds select --data-dir ../shared/mocap`` (docs/priors.md).
CLASSIFY_PARAMS: tuple[str, ...] = CANDIDATE_PARAMS["legs+shoulders"]
#: The between-activity switching probability per frame and the extra noise
#: (deg) the decoder assumes: chosen by the variant run of that CV with
#: leave-one-person-out folds and the ``"kinds"`` criterion (its command in
#: docs/priors.md); 1e-8 is the grid's smallest candidate.
CLASSIFY_SWITCH_PROB = 1e-8
CLASSIFY_EXTRA_NOISE_DEG = 4.0
CLASSIFY_INDEX: NDArray[np.intp] = np.array([PARAM_INDEX[n] for n in CLASSIFY_PARAMS], np.intp)
#: Candidate features of ``select_classifier_settings`` (the variant runs).
CANDIDATE_FEATURES: tuple[str, ...] = ("angles", "centred-4s", "velocity")
#: Candidate extra measurement noise (deg) the decoder assumes on top of the
#: test noise (inflating ``R`` tolerates a new person's postures and styles).
CANDIDATE_EXTRA_NOISE_DEG: tuple[float, ...] = (0.0, 2.0, 4.0, 8.0, 16.0)
#: The classifier's features by default: the angles (the CV's choice).
CLASSIFY_FEATURES = "angles"
#: How ``select_classifier_settings`` scores a setting: ``"kinds"`` the mean
#: of the pooled error of the style folds and that of the person folds (each
#: kind of "new" weighs the same, however many frames it has); ``"frames"``
#: every held-out frame weighs the same (the style folds dominate).
CV_CRITERIA: tuple[str, ...] = ("kinds", "frames")
#: Frames replaced by the B-spline on each side of a junction between two clips.
BLEND_FRAMES = 5
#: Clips per test sequence: drawn uniformly from this inclusive range.
CLIPS_PER_SEQUENCE = (2, 4)
#: The interpolation gap of Fig. 6: frames 50 to 99 (half-open 50:100).
GAP = (50, 100)


@dataclass(frozen=True)
class ClassifierSetting:
    """One candidate setting of the classifier.

    Attributes:
        params: The modelled parameter names.
        switch_prob: Between-activity switching probability per frame.
        name: Short name of the parameter subset.
        features: What the models see (:func:`parse_features`).
        extra_noise_deg: Measurement noise (deg) the decoder assumes on top of
            the test noise: ``R`` grows by its square (in the features' units).
    """

    params: tuple[str, ...]
    switch_prob: float
    name: str = ""
    features: str = "angles"
    extra_noise_deg: float = 0.0

    def __post_init__(self) -> None:
        parse_features(self.features)
        if not (self.extra_noise_deg >= 0 and np.isfinite(self.extra_noise_deg)):
            raise ValueError(
                f"ClassifierSetting: extra_noise_deg must be finite and >= 0, got "
                f"{self.extra_noise_deg}"
            )

    @property
    def fit_key(self) -> tuple[tuple[str, ...], str]:
        """What the models are fitted to: the parameters and the features."""
        return (tuple(self.params), self.features)

    @property
    def decode_key(self) -> tuple[float, float]:
        """What only the decoding changes: switch probability and extra noise (deg)."""
        return (float(self.switch_prob), float(self.extra_noise_deg))

    def label(self) -> str:
        """``"legs, 1e-03"``; non-default features and extra noise appended."""
        out = f"{self.name or '+'.join(self.params)}, {self.switch_prob:.0e}"
        if self.features != "angles":
            out += f", {self.features}"
        if self.extra_noise_deg:
            out += f", +{self.extra_noise_deg:g} deg"
        return out


def setting_name(params: Sequence[str]) -> str:
    """The candidate set's name for a parameter subset, else the names joined by ``+``."""
    for name, names in CANDIDATE_PARAMS.items():
        if tuple(names) == tuple(params):
            return name
    return "+".join(params)


def default_settings() -> dict[str, ClassifierSetting]:
    """The CV-chosen defaults and, for comparison, the old fixed settings."""
    return {
        "CV-chosen": ClassifierSetting(
            CLASSIFY_PARAMS,
            CLASSIFY_SWITCH_PROB,
            setting_name(CLASSIFY_PARAMS),
            CLASSIFY_FEATURES,
            CLASSIFY_EXTRA_NOISE_DEG,
        ),
        "old fixed": ClassifierSetting(
            OLD_CLASSIFY_PARAMS, OLD_CLASSIFY_SWITCH_PROB, setting_name(OLD_CLASSIFY_PARAMS)
        ),
    }


def param_indices(names: Sequence[str] | None) -> NDArray[np.intp] | None:
    """Indices of named parameters in the 25-vector (None for None).

    Raises:
        ValueError: Naming the unknown names.
    """
    if names is None:
        return None
    unknown = [n for n in names if n not in PARAM_INDEX]
    if unknown:
        raise ValueError(f"unknown parameter names {unknown}; see humotion_gym.body.PARAM_NAMES")
    return np.array([PARAM_INDEX[n] for n in names], dtype=np.intp)
