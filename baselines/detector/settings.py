"""How the detector's keypoints enter a likelihood: settings, as data (no torch).

:mod:`baselines.agents.specs` names these for the ``+det`` agents;
:mod:`baselines.detector.term` (which imports torch) builds the likelihood.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class DetectorTerm:
    """How the detections enter a likelihood.

    Attributes:
        sigma_scale: The Gaussian's sigma per keypoint, in multiples of the
            detector's validation error (its median over ``sqrt(2 ln 2)``).
        image_weight: The image likelihood's weight (0: the detections alone).
        unlabelled: Score each left/right pair by its better assignment (the
            detector's left and right taken as unreliable).
        cap: The most one keypoint's term costs, nats (inf: a plain Gaussian).

    Raises:
        ValueError: If a number is out of range.
    """

    sigma_scale: float = 1.0
    image_weight: float = 1.0
    unlabelled: bool = False
    cap: float = float("inf")

    def __post_init__(self) -> None:
        if not (np.isfinite(self.sigma_scale) and self.sigma_scale > 0):
            raise ValueError(
                f"DetectorTerm.sigma_scale: expected a positive number, got {self.sigma_scale}"
            )
        if not (np.isfinite(self.image_weight) and self.image_weight >= 0):
            raise ValueError(
                f"DetectorTerm.image_weight: expected a number >= 0, got {self.image_weight}"
            )
        if not self.cap > 0:
            raise ValueError(f"DetectorTerm.cap: expected a positive number, got {self.cap}")
