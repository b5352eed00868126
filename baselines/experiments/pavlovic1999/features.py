"""What the activity classifier's models see: the angles, centred angles or velocities.

Every feature is causal (frame ``t`` uses frames ``<= t`` only), so a test
sequence's features can be computed as it arrives.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import ArrayLike, NDArray

from humotion_gym.mocap.motion import Motion

FloatArray = NDArray[np.float64]

#: What the classifier's models see (:func:`feature_transform`; every one causal):
#: ``"angles"`` the angles themselves (the paper); ``"centred-Ns"`` the angles
#: less their causal running mean over the last N seconds (the cumulative mean
#: over the first N s; ``"centred-all"``: the cumulative mean from the start),
#: removing a person's posture offset; ``"velocity"`` the angles' first
#: differences per second (posture-free, but differencing doubles the noise's
#: variance).
FEATURES_HELP = "angles, centred-Ns (N seconds, or all), velocity"


def parse_features(features: str) -> tuple[str, float]:
    """The kind of a feature name and its window in seconds (``inf``: none or all).

    Args:
        features: ``"angles"``, ``"velocity"``, ``"centred-all"`` or
            ``"centred-Ns"`` with ``N`` a positive number of seconds.

    Returns:
        ``(kind, seconds)``, kind one of ``"angles"``, ``"centred"``, ``"velocity"``.

    Raises:
        ValueError: Naming ``features`` when it is none of these.
    """
    if features in ("angles", "velocity"):
        return features, float("inf")
    if features.startswith("centred-"):
        window = features[len("centred-") :]
        if window == "all":
            return "centred", float("inf")
        if window.endswith("s"):
            try:
                seconds = float(window[:-1])
            except ValueError:
                seconds = float("nan")
            if seconds > 0 and np.isfinite(seconds):
                return "centred", seconds
    raise ValueError(f"features: unknown {features!r}; expected {FEATURES_HELP}")


def running_mean(y: ArrayLike, window: float) -> FloatArray:
    """Causal running mean of ``y`` along the frames (axis 0).

    The mean at frame ``t`` uses frames ``0..t`` only: the cumulative mean for
    the first ``window`` frames, then an exponential moving average with weight
    ``1 / window`` on the newest frame (the two agree at the hand-over).

    Args:
        y: ``(T, D)`` values.
        window: Frames (> 0; ``inf``: the cumulative mean throughout).

    Raises:
        ValueError: If ``window`` is not positive.
    """
    x = np.asarray(y, dtype=np.float64)
    if not window > 0:
        raise ValueError(f"running_mean: window must be > 0 frames, got {window}")
    n_frames = x.shape[0]
    head = n_frames if not np.isfinite(window) else min(n_frames, max(int(round(window)), 1))
    out = np.empty_like(x)
    counts = np.arange(1, head + 1, dtype=np.float64).reshape((-1,) + (1,) * (x.ndim - 1))
    out[:head] = np.cumsum(x[:head], axis=0) / counts
    if head < n_frames:
        from scipy.signal import lfilter  # scipy.signal takes a second to import

        a = 1.0 / head
        zi = ((1.0 - a) * out[head - 1])[None]
        out[head:], _ = lfilter([a], [1.0, a - 1.0], x[head:], axis=0, zi=zi)
    return out


def feature_transform(angles: ArrayLike, features: str, fps: float) -> FloatArray:
    """The classifier's features of a sequence of angles (causal: frame t uses frames <= t).

    Args:
        angles: ``(T, D)`` angles (rad).
        features: A name of :data:`FEATURES_HELP` (:func:`parse_features`).
        fps: Frames per second.

    Returns:
        ``(T, D)``: the angles (``"angles"``); the angles less their running
        mean (:func:`running_mean`, ``"centred-Ns"``); the first differences
        times ``fps``, the first frame's taken as zero (``"velocity"``).
    """
    kind, seconds = parse_features(features)
    y = np.asarray(angles, dtype=np.float64)
    if kind == "angles":
        return y
    if kind == "centred":
        return y - running_mean(y, seconds * fps if np.isfinite(seconds) else np.inf)
    out = np.zeros_like(y)
    out[1:] = np.diff(y, axis=0) * fps
    return out


def feature_noise(features: str, noise_std: float, fps: float) -> float:
    """Standard deviation in the features of white noise ``noise_std`` on the angles.

    Centring leaves it (the running mean averages the noise away); a first
    difference doubles its variance and scales it by ``fps``.
    """
    kind, _ = parse_features(features)
    return noise_std * np.sqrt(2.0) * fps if kind == "velocity" else noise_std


def assumed_noise(features: str, noise_std: float, extra_noise_deg: float, fps: float) -> float:
    """The measurement noise the decoder assumes, in the features' units.

    The test noise ``noise_std`` (rad) and the extra noise ``extra_noise_deg``
    (deg) are independent, so their standard deviations add in quadrature;
    each is carried into the features by :func:`feature_noise`.
    """
    return float(np.hypot(
        feature_noise(features, noise_std, fps),
        feature_noise(features, float(np.radians(extra_noise_deg)), fps),
    ))  # fmt: skip


def motion_features(motion: Motion, features: str) -> Motion:
    """The clip with every parameter replaced by its features (the clip's own start is t=0)."""
    if parse_features(features)[0] == "angles":
        return motion
    return dataclasses.replace(
        motion, params=feature_transform(motion.params, features, motion.fps)
    )
