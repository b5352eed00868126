"""Figures 3, 5 and 6 of Pavlovic et al. (1999): segmentation, synthesis, interpolation."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from baselines.experiments._plotting import pyplot, save
from baselines.experiments.pavlovic1999.classification import ClassificationResult
from baselines.experiments.pavlovic1999.interpolation import InterpolationResult
from humotion_gym.body import PARAM_NAMES

FloatArray = NDArray[np.float64]


def _names(free: ArrayLike) -> list[str]:
    return [PARAM_NAMES[i] for i in np.asarray(free, dtype=np.intp)]


def plot_segmentation(
    result: ClassificationResult, path: str | Path, max_sequences: int = 6
) -> None:
    """Fig. 3: true and estimated activity of the first test sequences, with a knee angle."""
    plt = pyplot()
    seqs = result.sequences[:max_sequences]
    labels = sorted(set(result.model.state_labels.tolist()))
    code = {lab: k for k, lab in enumerate(labels)}
    fig, axes = plt.subplots(len(seqs), 1, figsize=(10, 1.9 * len(seqs)), squeeze=False)
    names = _names(result.model.free)
    knee = names.index("r_knee") if "r_knee" in names else 0
    for ax, seq, dec in zip(axes[:, 0], seqs, result.decoded, strict=False):
        t = np.arange(seq.truth.shape[0])
        ax.plot(t, np.degrees(seq.angles[:, knee]) / 90.0, color="0.7", lw=0.8, label=names[knee])
        ax.step(t, [code[v] for v in seq.truth], where="post", color="k", lw=2, label="true")
        ax.step(t, [code[v] + 0.05 for v in dec], where="post", color="tab:red", lw=1.2,
                label="estimated")  # fmt: skip
        ax.set_yticks(range(len(labels)), labels)
        for s in seq.starts[1:]:
            ax.axvline(s, color="tab:blue", lw=0.5, ls=":")
        err = float(np.mean(dec != seq.truth))
        ax.set_title(f"{len(seq.clips)} clips, error {100 * err:.1f}%", fontsize=9)
    axes[0, 0].legend(loc="upper right", fontsize=7, ncol=3)
    axes[-1, 0].set_xlabel("frame")
    fig.suptitle(
        f"SLDS classification: {100 * result.error:.1f}% error over {result.n_points} frames, "
        f"{result.n_sequences} sequences"
    )
    save(fig, path)


def plot_synthesis(
    poses: FloatArray,
    switches: NDArray[np.intp],
    free: ArrayLike,
    path: str | Path,
    fps: float = 30,
) -> None:
    """Fig. 5: synthesised angles (deg) with the switch states below."""
    plt = pyplot()
    names = _names(free)
    t = np.arange(poses.shape[0]) / fps
    fig, (ax, ax_s) = plt.subplots(
        2, 1, figsize=(10, 5), sharex=True, gridspec_kw={"height_ratios": [4, 1]}
    )
    for k, name in enumerate(names):
        ax.plot(t, np.degrees(poses[:, k]), lw=1, label=name)
    ax.set_ylabel("angle (deg)")
    ax.legend(fontsize=7, ncol=4)
    ax.set_title("SLDS synthesis (noise-driven)")
    ax_s.step(t, switches, where="post", color="k")
    ax_s.set_ylabel("switch")
    ax_s.set_yticks(range(int(switches.max()) + 1))
    ax_s.set_xlabel("time (s)")
    save(fig, path)


def plot_interpolation(
    result: InterpolationResult, free: ArrayLike, path: str | Path, n_angles: int = 4
) -> None:
    """Fig. 6: the gap filled by the SLDS, linear and spline interpolation."""
    plt = pyplot()
    names = _names(free)
    k = min(n_angles, len(names))
    fig, axes = plt.subplots(k, 1, figsize=(10, 2.0 * k), sharex=True, squeeze=False)
    t = np.arange(result.truth.shape[0])
    start, stop = result.gap
    sl = slice(start - 1, stop + 1)
    fills = [
        ("slds", "tab:red", "-", "SLDS (Viterbi)"),
        ("slds_mean", "tab:purple", "-", "SLDS (posterior mean)"),
        ("linear", "tab:blue", "--", "linear"),
        ("spline", "tab:green", ":", "spline"),
    ]
    for j, ax in enumerate(axes[:, 0]):
        ax.plot(t, np.degrees(result.truth[:, j]), color="k", lw=1.5, label="truth")
        for attr, colour, style, label in fills:
            fill = getattr(result, attr)
            if fill is not None:
                ax.plot(t[sl], np.degrees(fill[sl, j]), color=colour, ls=style, label=label)
        ax.axvspan(start, stop - 1, color="0.9")
        ax.set_ylabel(f"{names[j]} (deg)", fontsize=8)
    axes[0, 0].legend(fontsize=7, ncol=5)
    text = ", ".join(f"{k} {v:.1f}" for k, v in result.errors.items())
    axes[0, 0].set_title(
        f"{result.clip}: frames {start}-{stop - 1} removed; mean abs error (deg): {text}",
        fontsize=9,
    )
    axes[-1, 0].set_xlabel("frame")
    save(fig, path)
