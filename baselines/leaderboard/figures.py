"""The report's figures (matplotlib, the ``plots`` extra).

Error over the episode's frames per cell with 95% bands, lost-track survival
curves (Kaplan-Meier), IQMs with intervals per task and the aggregate scores
(Agarwal, Schwarzer, Castro, Courville & Bellemare, NeurIPS 2021; see
:mod:`baselines.leaderboard.stats`). Without matplotlib
(:func:`figures_available` is False) the report has its tables alone.
"""

from __future__ import annotations

import importlib.util
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from baselines.experiments._plotting import pyplot, save
from baselines.leaderboard import stats
from baselines.leaderboard.evaluation import run_interval
from baselines.leaderboard.rows import (
    by_clip,
    cell_label,
    episode_clips,
    ran,
    run_clusters,
    seed_matrix,
)


def figures_available() -> bool:
    """Whether matplotlib (the ``plots`` extra) is installed, so the report has figures."""
    return importlib.util.find_spec("matplotlib") is not None


def _tasks(rows: Sequence[dict[str, Any]]) -> list[str]:
    return list(dict.fromkeys(r["task"] for r in rows if ran(r)))


def _panels(tasks: list[str], width: float, height: float) -> tuple[Any, Any]:
    """A figure of one panel per task: the figure and its ``(axes, task)`` pairs."""
    size = (width * len(tasks), height)
    fig, axes = pyplot().subplots(1, len(tasks), figsize=size, squeeze=False)
    return fig, zip(axes[0], tasks, strict=True)


def _legend_or_note(ax: Any) -> None:
    """The cells' legend, or a note where no cell kept its per-frame series."""
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7)
    else:
        ax.text(0.5, 0.5, "no per-frame series kept", ha="center", transform=ax.transAxes)


def _has_series(row: dict[str, Any]) -> bool:
    return all(e.get("errors_mm") for e in row["episodes"])


def _errors_matrix(row: dict[str, Any]) -> NDArray[np.float64]:
    # episodes may end early when the run terminated on lost track: the common frames
    length = min(len(e["errors_mm"]) for e in row["episodes"])
    return np.array([e["errors_mm"][:length] for e in row["episodes"]], dtype=np.float64)


def error_band(
    row: dict[str, Any], seed: int = 0
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """A cell's mean error at each frame with its 95% band, over the frames every run has.

    The band resamples what the cell's mean error interval does
    (:func:`~baselines.leaderboard.evaluation.summarize`).

    Returns:
        ``(mean, low, high)`` (:func:`~baselines.leaderboard.stats.mean_band`).
    """
    eps, errors = row["episodes"], _errors_matrix(row)
    clips = by_clip(row)
    if run_clusters(eps, clips) is None:  # independent episodes
        return stats.mean_band(errors, seed=seed)
    episode_seeds, agent_seeds, _ = seed_matrix(eps)
    run = {(int(e["seed"]), int(e.get("agent_seed", 0))): k for k, e in enumerate(eps)}
    cube = errors[[[run[(s, a)] for a in agent_seeds] for s in episode_seeds]]
    return stats.mean_band(cube, seed=seed, clusters=episode_clips(eps) if clips else None)


def figure_error_over_frames(rows: Sequence[dict[str, Any]], path: Path, seed: int = 0) -> Path:
    """Mean error at each frame per cell, with 95% bands (:func:`error_band`)."""
    fig, panels = _panels(_tasks(rows), 5, 3.6)
    for ax, task in panels:
        # a record kept without its per-frame series (a summary of runs) has no curve
        with_series = (r for r in rows if ran(r) and r["task"] == task and _has_series(r))
        for r in with_series:
            mean, lo, hi = error_band(r, seed)
            frames = np.arange(mean.size)
            (line,) = ax.plot(frames, mean, lw=1.4, label=cell_label(r))
            ax.fill_between(frames, lo, hi, color=line.get_color(), alpha=0.2, lw=0)
        ax.set(title=task, xlabel="frame", ylabel="keypoint error, mm")
        _legend_or_note(ax)
    return save(fig, path)


def figure_survival(rows: Sequence[dict[str, Any]], path: Path) -> Path:
    """Fraction of episodes still tracking after each frame (Kaplan-Meier, 95% band)."""
    fig, panels = _panels(_tasks(rows), 5, 3.6)
    for ax, task in panels:
        for r in (r for r in rows if ran(r) and r["task"] == task and _has_series(r)):
            eps = r["episodes"]
            length = max(len(e["errors_mm"]) for e in eps)
            curve = stats.survival(
                [e["lost_frame"] for e in eps], [len(e["errors_mm"]) for e in eps]
            )
            frames = np.append(curve["frames"], length)
            step = [np.append(curve[k], curve[k][-1]) for k in ("survival", "low", "high")]
            (line,) = ax.step(frames, step[0], where="post", lw=1.4, label=cell_label(r))
            ax.fill_between(frames, step[1], step[2], step="post", color=line.get_color(),
                            alpha=0.15, lw=0)  # fmt: skip
        ax.set(title=task, xlabel="frame", ylabel="still tracking", ylim=(-0.02, 1.02))
        _legend_or_note(ax)
    return save(fig, path)


def iqm_interval(row: dict[str, Any], seed: int = 0) -> list[float]:
    """A cell's IQM interval as its summary draws it (``iqm_error_ci`` of ``summarize``)."""
    eps = row["episodes"]
    values = [e["mean_error_mm"] for e in eps]
    return run_interval(values, run_clusters(eps, by_clip(row)), stats.iqm, seed)


def figure_iqm_per_task(rows: Sequence[dict[str, Any]], path: Path, seed: int = 0) -> Path:
    """Each cell's IQM error with its 95% interval (:func:`iqm_interval`), one panel per task."""
    tasks = _tasks(rows)
    n_cells = max(sum(1 for r in rows if ran(r) and r["task"] == t) for t in tasks)
    fig, panels = _panels(tasks, 4.4, 0.9 + 0.32 * n_cells)
    for ax, task in panels:
        cells = [r for r in rows if ran(r) and r["task"] == task]
        values = [stats.iqm([e["mean_error_mm"] for e in r["episodes"]]) for r in cells]
        cis = [iqm_interval(r, seed) for r in cells]
        y = np.arange(len(cells))[::-1]
        err = np.abs(np.array(cis).T - np.array(values))
        ax.errorbar(values, y, xerr=err, fmt="o", capsize=3)
        ax.set_yticks(y, [cell_label(r) for r in cells], fontsize=8)
        ax.set(title=task, xlabel="IQM keypoint error, mm (95% CI)")
        ax.grid(axis="x", alpha=0.3)
    return save(fig, path)


def figure_aggregate(aggregates: Sequence[dict[str, Any]], path: Path) -> Path:
    """IQM normalised score and P(beats hold) per cell, with 95% intervals."""
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(9, 0.9 + 0.32 * len(aggregates)), squeeze=False)
    y = np.arange(len(aggregates))[::-1]
    labels = [a["cell"] for a in aggregates]
    for ax, key, xlabel, ref in (
        (axes[0, 0], "iqm_score", "IQM score (error / hold's)", 1.0),
        (axes[0, 1], "beats_reference", "P(beats hold)", 0.5),
    ):
        values = np.array([a[key] for a in aggregates])
        cis = np.array([a[f"{key}_ci"] for a in aggregates]).T
        ax.errorbar(values, y, xerr=np.abs(cis - values), fmt="o", capsize=3)
        ax.axvline(ref, color="grey", ls="--", lw=1)
        ax.set_yticks(y, labels, fontsize=8)
        ax.set(xlabel=xlabel)
        ax.grid(axis="x", alpha=0.3)
    return save(fig, path)
