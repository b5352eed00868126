"""Experiments and figures of Ormoneit, Black, Hastie & Kjellström (2005) for the cyclic PCA prior.

*Representing cyclic human motion using functional analysis*, Image and Vision
Computing 23 (2005). The model is :mod:`baselines.priors.cyclic_pca` (with
:mod:`~baselines.priors.cycles` and :mod:`~baselines.priors.fpca`); this
module holds what the paper measures and draws with it:

* the cycle length of each clip by eq. 3 against the one read off the feet
  (:func:`cycle_lengths`, ``humotion-gym pca period``);
* figures like the paper's Figs. 5, 7, 9 and 10 (:func:`make_figures`,
  ``humotion-gym pca figures``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from baselines.experiments._plotting import pyplot, save
from baselines.priors import cycles, fpca
from baselines.priors.cyclic_pca import WALK_LABELS, joint_series
from humotion_gym.body import KEYPOINT_INDEX, PARAM_NAMES
from humotion_gym.mocap.library import MotionLibrary
from humotion_gym.mocap.motion import Motion

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class CycleLength:
    """The cycle length of one clip, from eq. 3 and from the feet.

    Attributes:
        clip_id: The clip.
        fps: Its frame rate.
        frames_snr: Cycle length maximising eq. 3 over the joint angles, frames.
        frames_feet: Median interval between every other maximum of the ankles'
            separation (one stride = two steps), frames.
        steps: Maxima of the ankles' separation found.
        n_frames: The clip's frames.
        still: Eq. 3 saw no cycle at any period the clip shows twice (no joint
            angle observed often enough, or none moves).
    """

    clip_id: str
    fps: float
    frames_snr: float
    frames_feet: float
    steps: int
    n_frames: int
    still: bool = False

    @property
    def seconds_snr(self) -> float:
        """Eq. 3's cycle length in seconds."""
        return self.frames_snr / self.fps

    @property
    def seconds_feet(self) -> float:
        """The feet's cycle length in seconds."""
        return self.frames_feet / self.fps

    @property
    def relative_difference(self) -> float:
        """``|snr - feet| / feet``."""
        return abs(self.frames_snr - self.frames_feet) / self.frames_feet

    @property
    def too_short(self) -> str | None:
        """Why eq. 3 gave no cycle length (the clip is too short), or None when it gave one.

        :func:`~baselines.priors.cycles.estimate_period` tries periods it sees
        twice in the clip: none when the clip is shorter than two of the
        shortest period tried, and it gives none when its ratio is highest at
        the longest period the clip shows twice (the cycle may be longer).
        """
        if np.isfinite(self.frames_snr):
            return None
        tried = cycles.candidate_periods(self.fps)
        shortest, longest = float(tried[0]), float(tried[-1])
        if self.still and self.n_frames >= 2 * shortest:
            return (
                "no cycle to measure: no joint angle is observed often enough and moves in its "
                f"{self.n_frames} frames"
            )
        start = f"too short to estimate a cycle length: {self.n_frames} frames"
        if self.n_frames < 2 * shortest:
            return (
                f"{start}, fewer than the {2 * shortest:g} that two cycles of the shortest "
                f"period tried ({shortest / self.fps:g} s) take"
            )
        return (
            f"{start} show two cycles of at most {self.n_frames / 2:g} frames, where eq. 3 still "
            f"rises; two cycles of the longest period tried ({longest / self.fps:g} s) take "
            f"{2 * longest:g} frames"
        )

    def as_dict(self) -> dict[str, float | int | str | None]:
        """Plain dict for JSON (NaN where a cycle length was not found)."""
        return {
            "clip": self.clip_id,
            "fps": self.fps,
            "n_frames": self.n_frames,
            "frames_snr": round(self.frames_snr, 3),
            "frames_feet": round(self.frames_feet, 3),
            "seconds_snr": round(self.seconds_snr, 4),
            "seconds_feet": round(self.seconds_feet, 4),
            "steps": self.steps,
            "too_short": self.too_short,
        }


def foot_cycle_length(motion: Motion) -> tuple[float, int]:
    """Cycle length from the feet: the ankles' separation peaks at every step.

    The separation of the two ankle keypoints (the source's ``Motion.keypoints``
    where observed, else the cone body's forward kinematics) has a local maximum
    at each step (feet furthest apart, around heel strike); a gait cycle is two
    steps, so the cycle length is the median distance between every other
    maximum.

    Returns:
        ``(frames, number of maxima)``; NaN frames with fewer than three maxima.
    """
    from scipy.signal import find_peaks  # scipy.signal takes a second to import

    r, l_ = KEYPOINT_INDEX["r_ankle"], KEYPOINT_INDEX["l_ankle"]
    kp = motion.keypoints[:, [r, l_]]
    if not np.all(np.isfinite(kp)):
        kp = motion.body_keypoints()[:, [r, l_]]
    sep = np.linalg.norm(kp[:, 0] - kp[:, 1], axis=-1)
    spread = float(np.ptp(sep)) if sep.size else 0.0
    peaks, _ = find_peaks(sep, distance=max(2, int(0.25 * motion.fps)), prominence=0.2 * spread)
    if peaks.size < 3:
        return float("nan"), int(peaks.size)
    # Sub-frame peak positions: the vertex of the parabola through each maximum
    # and its two neighbours.
    inner = np.clip(peaks, 1, sep.size - 2)
    left, mid, right = sep[inner - 1], sep[inner], sep[inner + 1]
    curvature = left - 2 * mid + right
    shift = np.where(curvature < 0, 0.5 * (left - right) / np.where(curvature < 0, curvature, 1), 0)
    where = inner + np.clip(shift, -0.5, 0.5)
    return float(np.median(where[2:] - where[:-2])), int(peaks.size)


def cycle_lengths(motions: Sequence[Motion]) -> list[CycleLength]:
    """Per clip, the cycle length from eq. 3 and from the foot keypoints."""
    out = []
    for m in motions:
        joint = cycles.JOINT_ANGLES
        angles, seen = m.params[:, joint], m.observed[:, joint]
        p = cycles.estimate_period(angles, seen, m.fps)
        still = bool(np.isnan(p)) and not np.any(cycles.period_ratios(angles, seen, m.fps)[1] > 0)
        feet, steps = foot_cycle_length(m)
        out.append(CycleLength(m.clip_id, float(m.fps), p, feet, steps, m.n_frames, still))
    return out


def plot_snr(
    series: ArrayLike,
    path: str | Path,
    observed: ArrayLike | None = None,
    fps: float = 30.0,
    angle_names: Sequence[str] | None = None,
    rng: np.random.Generator | None = None,
    title: str = "",
) -> FloatArray:
    """Figure like the paper's Fig. 5: ``snr(p)`` per angle, summed, and for white noise.

    Args:
        series: ``(T, J)`` angles of one clip.
        path: Image file to write.
        observed: Its mask.
        fps: Frame rate (the x axis is in seconds and frames).
        angle_names: Legend names (default: the joint-angle names).
        rng: Generator for the white-noise series (seed 0 when None).
        title: Figure title.

    Returns:
        ``(P,)`` the candidate periods plotted, in frames.
    """
    plt = pyplot()

    x = np.asarray(series, dtype=np.float64)
    periods = cycles.candidate_periods(fps, x.shape[0])
    per_angle = cycles.signal_to_noise(x, observed, periods)
    rng = np.random.default_rng(0) if rng is None else rng
    noise = cycles.signal_to_noise(rng.standard_normal(x.shape), None, periods)
    names = angle_names or [PARAM_NAMES[i] for i in cycles.JOINT_ANGLES][: x.shape[1]]
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 4.5))
    for j in range(per_angle.shape[1]):
        ax1.plot(periods / fps, per_angle[:, j], lw=0.8, label=names[j] if j < len(names) else "")
    ax1.set_xlabel("candidate cycle length p (s)")
    ax1.set_ylabel("signal / noise, eq. 3 per angle")
    ax1.set_yscale("log")
    ax1.legend(fontsize=5, ncol=2)
    total = per_angle.sum(axis=1)
    best = periods[int(np.argmax(total))]
    ax2.plot(periods / fps, total, "k", lw=1.5, label="walking clip, summed over angles")
    ax2.plot(periods / fps, noise.sum(axis=1), "r", lw=1.0, label="white noise, summed")
    ax2.axvline(best / fps, color="k", ls=":", lw=0.8)
    ax2.set_xlabel("candidate cycle length p (s)")
    ax2.set_ylabel("summed signal / noise (eq. 3)")
    ax2.set_yscale("log")
    ax2.set_title(f"argmax p = {best:.2f} frames = {best / fps:.3f} s")
    ax2.legend(fontsize=8)
    if title:
        fig.suptitle(title)
    save(fig, path, dpi=120)
    return periods


def plot_aligned(
    alignment: cycles.Alignment,
    sequences: Sequence[ArrayLike],
    path: str | Path,
    observed: Sequence[ArrayLike] | None = None,
    angles: Sequence[int] | None = None,
    angle_names: Sequence[str] | None = None,
) -> None:
    """Figure like the paper's Fig. 7: every sequence's frames at their aligned phase.

    Args:
        alignment: Result of :func:`~baselines.priors.cycles.align_offsets`.
        sequences: The same sequences.
        path: Image file to write.
        observed: Their masks.
        angles: Which angle columns to draw (default: the 6 whose reference
            curves swing the most).
        angle_names: Names of all angle columns.
    """
    plt = pyplot()

    xs, ws = cycles.check_sequences(sequences, observed)
    n_angles = xs[0].shape[1]
    names = angle_names or [PARAM_NAMES[i] for i in cycles.JOINT_ANGLES][:n_angles]
    grid = np.linspace(0, 1, 200)
    ref = alignment.reference(grid)
    if angles is None:
        angles = list(np.argsort(np.ptp(ref, axis=0))[::-1][: min(6, n_angles)])
    cols = min(3, len(angles))
    rows = int(np.ceil(len(angles) / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.2 * rows), squeeze=False)
    for ax, j in zip(axes.ravel(), angles, strict=False):
        for i, (x, w) in enumerate(zip(xs, ws, strict=True)):
            ph = alignment.phases(i, x.shape[0])
            ok = w[:, j]
            ax.plot(ph[ok], np.degrees(x[ok, j]), ".", ms=1.5, alpha=0.35)
        ax.plot(grid, np.degrees(ref[:, j]), "k", lw=2)
        ax.set_title(names[j], fontsize=9)
        ax.set_xlabel("phase")
        ax.set_ylabel("deg")
    for ax in axes.ravel()[len(angles) :]:
        ax.axis("off")
    fig.suptitle(f"{len(xs)} sequences aligned over the reference curves (Fig. 7)")
    save(fig, path, dpi=120)


def plot_components(
    result: fpca.FPCAResult,
    path: str | Path,
    angle_names: Sequence[str],
    n_show: int = 3,
    title: str = "",
    show_groups: bool = False,
) -> None:
    """Figure like the paper's Figs. 9 and 10: mean and leading components per angle.

    Each panel is one angle: the mean curve (black) and ``mean +- 2 sd_k v_k``
    for the first ``n_show`` components; with ``show_groups`` the per-group
    (per-subject) mean curves are drawn thin and grey.

    Args:
        result: A fitted :class:`~baselines.priors.fpca.FPCAResult`.
        path: Image file to write.
        angle_names: ``J`` names for the panels.
        n_show: Components to draw.
        title: Figure title.
        show_groups: Draw the group means too (Fig. 10).
    """
    plt = pyplot()

    j, s = result.mean.shape
    cols = 5
    rows = int(np.ceil(j / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(3.0 * cols, 2.3 * rows), squeeze=False)
    phase = np.arange(s) / s
    colours = ["tab:red", "tab:blue", "tab:green", "tab:orange", "tab:purple"]
    sd = result.component_std
    for a, ax in enumerate(axes.ravel()):
        if a >= j:
            ax.axis("off")
            continue
        if show_groups:
            for g in result.group_means:
                ax.plot(phase, np.degrees(g[a]), color="0.7", lw=0.6)
        ax.plot(phase, np.degrees(result.mean[a]), "k", lw=1.8)
        for k in range(min(n_show, result.n_components)):
            for sign, style in ((1, "-"), (-1, "--")):
                curve = result.mean[a] + sign * 2 * sd[k] * result.components[k, a]
                label = f"mean {'+' if sign > 0 else '-'} 2 sd PC{k + 1}" if a == 0 else None
                ax.plot(phase, np.degrees(curve), style, color=colours[k % 5], lw=0.9, label=label)
        ax.set_title(angle_names[a] if a < len(angle_names) else str(a), fontsize=8)
        ax.tick_params(labelsize=6)
    axes.ravel()[0].legend(fontsize=5)
    if title:
        fig.suptitle(title)
    save(fig, path)


def make_figures(
    library: MotionLibrary, out_dir: str | Path, fps: float = 30.0, components: int = 5
) -> tuple[list[Path], str]:
    """Figures like the paper's Figs. 5, 7, 9 and 10 from the training split's walks.

    Args:
        library: The motion library (only its train split's walking clips are used).
        out_dir: Folder for the PNG files (created).
        fps: The library's frame rate.
        components: Principal components of the FPCA.

    Returns:
        The files written and a one-line description of the data.

    Raises:
        ValueError: If the train split has no walking clip.
    """
    clips = [m for m in library.split("train") if m.label in WALK_LABELS]
    if not clips:
        raise ValueError("no walking clips in the library's train split")
    out = Path(out_dir)
    joint = cycles.JOINT_ANGLES
    names = [PARAM_NAMES[i] for i in joint]
    xs, ws = joint_series([m.params for m in clips], [m.observed for m in clips])
    periods = np.array([cycles.estimate_period(x, w, fps) for x, w in zip(xs, ws, strict=True)])
    keep = np.flatnonzero(np.isfinite(periods))
    if keep.size == 0:
        raise ValueError(
            f"no walking clip of the {len(clips)} shows a gait period at {fps:g} Hz "
            "(two whole cycles are needed; a rate below a few Hz cannot show one)"
        )
    xs, ws, periods = [xs[i] for i in keep], [ws[i] for i in keep], periods[keep]
    subjects = [clips[i].subject for i in keep]
    out.mkdir(parents=True, exist_ok=True)
    files = ("fig5_snr", "fig7_aligned", "fig9_components", "fig10_per_subject")
    written = [out / f"{name}.png" for name in files]
    fig5, fig7, fig9, fig10 = written
    plot_snr(xs[0], fig5, ws[0], fps, names, title=clips[keep[0]].clip_id)
    alignment = cycles.align_offsets(xs, periods, ws)
    plot_aligned(alignment, xs, fig7, ws, angle_names=names)
    seg = cycles.segment(xs, periods, alignment.offsets, ws)
    across = fpca.fpca(seg.values, seg.observed, n_components=components)
    plot_components(across, fig9, names, title="mean and components across subjects")
    groups = np.array([subjects[i] for i in seg.sequence])
    per_subject = fpca.fpca(seg.values, seg.observed, n_components=components, groups=groups)
    plot_components(
        per_subject, fig10, names, title="components with per-subject means", show_groups=True
    )
    kind = " (synthetic)" if library.is_synthetic else ""
    about = f"{len(xs)} walking clips{kind}, {seg.n_cycles} cycles, {len(set(subjects))} subjects"
    return written, about
