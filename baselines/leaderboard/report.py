"""The leaderboard report: one folder of tables, figures, videos and an ``index.html``.

:func:`write_report` takes the rows of :func:`baselines.leaderboard.run_leaderboard`
(or of a saved results file, :func:`load_rows`) and writes into one folder:

* ``tables.md``: the leaderboard table (the columns of
  :func:`baselines.leaderboard.markdown_table`, which the README pastes), the
  per-cell statistics (IQM with its interval, lost-track fraction with its
  Wilson interval, median lost frame), the aggregate over tasks (normalised
  score against ``hold``, IQM with a stratified bootstrap interval) and the
  probability that one cell beats another on a random episode; failed and
  skipped cells are listed with their reason;
* ``stats.json``: the same numbers, machine-readable;
* figures (matplotlib, the ``plots`` extra; without it the report says so and
  writes the rest): error over the episode's frames per cell with 95% bands,
  lost-track survival curves (Kaplan-Meier), IQMs with intervals per task, the
  aggregate scores;
* ``videos/``: the best, median and worst episode of each cell re-run with the
  estimate drawn over the frame (WebM, VP8, plays in browsers) and a contact
  sheet of each (JPEG); re-running an episode must reproduce its recorded
  errors, or the report stops (:class:`ReplayMismatch`);
* ``index.html``: all of it on one static page, tables sortable by a click on
  a column (a few lines of inline JavaScript, no external assets).

The statistics follow Agarwal, Schwarzer, Castro, Courville & Bellemare, *Deep
reinforcement learning at the edge of the statistical precipice*, NeurIPS 2021
(see :mod:`baselines.stats`).
"""

from __future__ import annotations

import html
import json
import os
import re
from collections.abc import Callable, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from baselines import stats
from baselines.evaluation import EpisodeResult, summarize

#: The reference each task's scores are normalised by.
REFERENCE = "hold"
#: Which episodes of a cell get a video.
VIDEO_CHOICES: tuple[str, ...] = ("best", "median", "worst")
#: Caption of the normalised score, shown under the aggregate table.
SCORE_LEGEND = (
    "score: an episode's mean keypoint error over hold's on the same episode (same task, "
    "same seed): below 1 beats holding the initial pose, 0.5 halves its error. IQM: "
    "interquartile mean over all tasks' episodes, 95% stratified bootstrap interval "
    "(episodes resampled within each task; Agarwal et al., NeurIPS 2021). P(beats hold): "
    "probability that a random episode of the cell has a lower error than a random "
    "episode of hold on the same task, averaged over tasks."
)


class ReplayMismatch(RuntimeError):
    """A re-run episode did not reproduce the errors recorded for it."""


# ------------------------------------------------------------------ input


def load_rows(path: str | Path) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """Rows and run settings of a saved leaderboard.

    Accepts the bare list of rows that ``humotion-gym leaderboard --out``
    writes, or a JSON object with a ``rows`` list (a results file), whose
    other keys (e.g. ``env_kwargs``, ``seed``) are returned as the settings.

    Raises:
        OSError: If the file cannot be read.
        ValueError: If it is not such a JSON document (the message names the file).
    """
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not JSON ({exc})") from None
    settings: dict[str, Any] = {}
    if isinstance(data, dict):
        if not isinstance(data.get("rows"), list):
            raise ValueError(f"{path}: expected a list of rows or an object with a 'rows' list")
        settings = {k: v for k, v in data.items() if k != "rows"}
        data = data["rows"]
    if not isinstance(data, list) or not all(
        isinstance(r, dict) and {"task", "agent", "particles"} <= r.keys() for r in data
    ):
        raise ValueError(f"{path}: expected rows with task, agent and particles")
    return data, settings


def ran(row: dict[str, Any]) -> bool:
    """Whether a row has episodes (it was neither skipped nor failed)."""
    return "summary" in row and "skipped" not in row and "error" not in row


# ------------------------------------------------------------------ tables


def _fmt(value: float | None, digits: int = 0) -> str:
    return "-" if value is None or not np.isfinite(value) else f"{value:,.{digits}f}"


def _ci(pair: Sequence[float], digits: int = 0) -> str:
    return f"{_fmt(pair[0], digits)}-{_fmt(pair[1], digits)}"


def statistics_table(rows: Sequence[dict[str, Any]]) -> list[list[str]]:
    """Per-cell statistics: header then one list of cells per row that ran."""
    out = [
        [
            "task", "agent", "particles", "episodes", "mean error mm (95% CI)",
            "IQM mm (95% CI)", "lost track (95% CI)", "median lost frame", "ms/frame",
        ]
    ]  # fmt: skip
    for r in rows:
        if not ran(r):
            continue
        s = r["summary"]
        iqm_ci = s.get("iqm_error_ci", [float("nan")] * 2)
        lost_ci = s.get("lost_fraction_ci", [float("nan")] * 2)
        out.append(
            [
                r["task"], r["agent"], _fmt(r["particles"]) if r["particles"] else "-",
                str(s["episodes"]),
                f"{_fmt(s['mean_error_mm'])} ({_ci(s['mean_error_ci'])})",
                f"{_fmt(s['iqm_error_mm'])} ({_ci(iqm_ci)})",
                f"{s['lost_fraction']:.0%} ({_fmt(100 * lost_ci[0])}-{_fmt(100 * lost_ci[1])}%)",
                _fmt(s.get("median_lost_frame")), f"{s['ms_per_frame']:.1f}",
            ]
        )  # fmt: skip
    return out


def aggregate_table(aggregates: Sequence[dict[str, Any]]) -> list[list[str]]:
    """The across-task aggregate: header then one row per cell."""
    out = [
        [
            "agent", "tasks", "episodes", "IQM score (95% CI)", "mean score (95% CI)",
            "P(beats hold) (95% CI)",
        ]
    ]  # fmt: skip
    for a in aggregates:
        out.append(
            [
                a["cell"], str(len(a["tasks"])), str(a["episodes"]),
                f"{a['iqm_score']:.2f} ({_ci(a['iqm_score_ci'], 2)})",
                f"{a['mean_score']:.2f} ({_ci(a['mean_score_ci'], 2)})",
                f"{a['beats_reference']:.2f} ({_ci(a['beats_reference_ci'], 2)})",
            ]
        )  # fmt: skip
    return out


def improvement_table(pairs: Sequence[dict[str, Any]]) -> list[list[str]]:
    """P(X beats Y) for each ordered pair: header then rows."""
    out = [["X", "Y", "tasks", "P(X beats Y) (95% CI)"]]
    for p in pairs:
        out.append(
            [p["x"], p["y"], str(len(p["tasks"])), f"{p['probability']:.2f} ({_ci(p['ci'], 2)})"]
        )
    return out


def failures_table(rows: Sequence[dict[str, Any]]) -> list[list[str]]:
    """Cells that did not run: header then (task, agent, particles, status, reason)."""
    out = [["task", "agent", "particles", "status", "reason"]]
    for r in rows:
        if "error" in r or "skipped" in r:
            status = "error" if "error" in r else "skipped"
            reason = str(r.get("error", r.get("skipped", "")))
            out.append(
                [r["task"], r["agent"], _fmt(r["particles"]) if r["particles"] else "-",
                 status, reason]
            )  # fmt: skip
    return out


def _markdown(table: list[list[str]]) -> str:
    def line(cells: list[str]) -> str:
        return "| " + " | ".join(c.replace("|", "/") for c in cells) + " |"

    return "\n".join([line(table[0]), "|" + "---|" * len(table[0])] + [line(r) for r in table[1:]])


def markdown_report(rows: Sequence[dict[str, Any]], computed: dict[str, Any]) -> str:
    """``tables.md``: the leaderboard table, statistics, aggregate, failures."""
    from baselines.leaderboard import markdown_table, validity_lines

    good = [r for r in rows if ran(r)]
    # every row: markdown_table shows a cell that did not run with its reason
    parts = ["# Leaderboard", "", markdown_table(rows), ""]
    parts += [f"- {line}" for line in validity_lines(good)] + [""]
    parts += ["## Cell statistics", "", _markdown(statistics_table(rows)), ""]
    if computed["aggregate"]:
        parts += ["## Across tasks (normalised by hold)", ""]
        parts += [_markdown(aggregate_table(computed["aggregate"])), "", SCORE_LEGEND, ""]
    if computed["pairwise"]:
        parts += ["## Probability of improvement", ""]
        parts += [_markdown(improvement_table(computed["pairwise"])), ""]
    failures = failures_table(rows)
    if len(failures) > 1:
        parts += ["## Cells that did not run", "", _markdown(failures), ""]
    return "\n".join(parts)


def compute(rows: Sequence[dict[str, Any]], seed: int = 0) -> dict[str, Any]:
    """Every statistic of the report (``stats.json``): cells, aggregate, pairwise."""
    cells = []
    for r in rows:
        if ran(r):
            cells.append(
                {"task": r["task"], "agent": r["agent"], "particles": r["particles"],
                 "summary": summarize(r["episodes"], seed=seed)}
            )  # fmt: skip
    return {
        "reference": REFERENCE,
        "seed": seed,
        "cells": cells,
        "aggregate": stats.aggregate(rows, REFERENCE, seed=seed),
        "pairwise": stats.pairwise_improvement(rows, seed=seed),
    }


# ------------------------------------------------------------------ figures


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _tasks(rows: Sequence[dict[str, Any]]) -> list[str]:
    return list(dict.fromkeys(r["task"] for r in rows if ran(r)))


def _errors_matrix(row: dict[str, Any]) -> NDArray[np.float64]:
    # episodes may end early when the run terminated on lost track: the common frames
    length = min(len(e["errors_mm"]) for e in row["episodes"])
    return np.array([e["errors_mm"][:length] for e in row["episodes"]], dtype=np.float64)


def figure_error_over_frames(rows: Sequence[dict[str, Any]], path: Path, seed: int = 0) -> Path:
    """Mean error at each frame per cell, with 95% bootstrap bands over episodes."""
    plt = _pyplot()
    tasks = _tasks(rows)
    fig, axes = plt.subplots(1, len(tasks), figsize=(5 * len(tasks), 3.6), squeeze=False)
    for ax, task in zip(axes[0], tasks, strict=True):
        for r in (r for r in rows if ran(r) and r["task"] == task):
            mean, lo, hi = stats.mean_band(_errors_matrix(r), seed=seed)
            frames = np.arange(mean.size)
            (line,) = ax.plot(frames, mean, lw=1.4, label=stats.cell_label(r))
            ax.fill_between(frames, lo, hi, color=line.get_color(), alpha=0.2, lw=0)
        ax.set(title=task, xlabel="frame", ylabel="keypoint error, mm")
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def figure_survival(rows: Sequence[dict[str, Any]], path: Path) -> Path:
    """Fraction of episodes still tracking after each frame (Kaplan-Meier, 95% band)."""
    plt = _pyplot()
    tasks = _tasks(rows)
    fig, axes = plt.subplots(1, len(tasks), figsize=(5 * len(tasks), 3.6), squeeze=False)
    for ax, task in zip(axes[0], tasks, strict=True):
        for r in (r for r in rows if ran(r) and r["task"] == task):
            eps = r["episodes"]
            length = max(len(e["errors_mm"]) for e in eps)
            curve = stats.survival(
                [e["lost_frame"] for e in eps], [len(e["errors_mm"]) for e in eps]
            )
            frames = np.append(curve["frames"], length)
            step = [np.append(curve[k], curve[k][-1]) for k in ("survival", "low", "high")]
            (line,) = ax.step(frames, step[0], where="post", lw=1.4, label=stats.cell_label(r))
            ax.fill_between(frames, step[1], step[2], step="post", color=line.get_color(),
                            alpha=0.15, lw=0)  # fmt: skip
        ax.set(title=task, xlabel="frame", ylabel="still tracking", ylim=(-0.02, 1.02))
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def figure_iqm_per_task(rows: Sequence[dict[str, Any]], path: Path, seed: int = 0) -> Path:
    """Each cell's IQM error with its 95% interval, one panel per task."""
    plt = _pyplot()
    tasks = _tasks(rows)
    n_cells = max(sum(1 for r in rows if ran(r) and r["task"] == t) for t in tasks)
    height = 0.9 + 0.32 * n_cells
    fig, axes = plt.subplots(1, len(tasks), figsize=(4.4 * len(tasks), height), squeeze=False)
    for ax, task in zip(axes[0], tasks, strict=True):
        cells = [r for r in rows if ran(r) and r["task"] == task]
        values = [stats.iqm([e["mean_error_mm"] for e in r["episodes"]]) for r in cells]
        cis = [
            stats.bootstrap_ci([e["mean_error_mm"] for e in r["episodes"]], stats.iqm, seed=seed)
            for r in cells
        ]
        y = np.arange(len(cells))[::-1]
        err = np.abs(np.array(cis).T - np.array(values))
        ax.errorbar(values, y, xerr=err, fmt="o", capsize=3)
        ax.set_yticks(y, [stats.cell_label(r) for r in cells], fontsize=8)
        ax.set(title=task, xlabel="IQM keypoint error, mm (95% CI)")
        ax.grid(axis="x", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def figure_aggregate(aggregates: Sequence[dict[str, Any]], path: Path) -> Path:
    """IQM normalised score and P(beats hold) per cell, with 95% intervals."""
    plt = _pyplot()
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
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


# ------------------------------------------------------------------ videos


def choose_episodes(row: dict[str, Any]) -> dict[str, int]:
    """The seeds of a cell's best, median and worst episode by mean error.

    The median is the lower middle of the sorted episodes; ties go to the
    smaller seed. A choice may share a seed with another (few episodes).
    """
    ranked = sorted(row["episodes"], key=lambda e: (e["mean_error_mm"], e["seed"]))
    return {
        "best": int(ranked[0]["seed"]),
        "median": int(ranked[(len(ranked) - 1) // 2]["seed"]),
        "worst": int(ranked[-1]["seed"]),
    }


def replay_episodes(
    row: dict[str, Any],
    seeds: Sequence[int],
    env_kwargs: dict[str, Any] | None = None,
) -> dict[int, tuple[EpisodeResult, list[NDArray[np.uint8]]]]:
    """Re-run a cell's episodes with rendering; check they reproduce the recorded errors.

    Each episode is re-run on its own with
    :func:`baselines.engine.run_cell_episode`, with the agent seeded by the
    cell's first episode seed (the leaderboard's seed). Without that engine
    (an older checkout), the cell's episodes up to the last chosen one are
    re-run in order with one agent, as the old in-process loop ran them.

    Args:
        row: A leaderboard row that ran.
        seeds: Episode seeds to record.
        env_kwargs: The environment's keyword arguments of the run (difficulty, data).

    Returns:
        ``{seed: (result, frames)}``; each frame is the rendered frame with
        the estimate drawn over it.

    Raises:
        ReplayMismatch: If a re-run's per-frame errors differ from the recorded ones.
    """
    import gymnasium as gym

    from baselines.agents import make
    from baselines.evaluation import run_episode

    recorded = {int(e["seed"]): e for e in row["episodes"]}
    missing = [s for s in seeds if s not in recorded]
    if missing:
        raise ValueError(f"seeds: {missing} are not episodes of {stats.cell_label(row)}")
    first = min(recorded)
    settings = {**(env_kwargs or {}), "render_mode": "rgb_array"}
    wanted = sorted(set(int(s) for s in seeds))
    out: dict[int, tuple[EpisodeResult, list[NDArray[np.uint8]]]] = {}
    engine_episode = _engine_episode()
    if engine_episode is not None:
        for s in wanted:
            frames: list[NDArray[np.uint8]] = []
            result = engine_episode(
                row["task"], row["agent"], row["particles"], s, first, settings,
                on_frame=lambda f, i, frames=frames: frames.append(f),
            )  # fmt: skip
            out[s] = (result, frames)
    else:
        import humotion_gym  # noqa: F401  (registers the env ids)

        env = gym.make(f"humotion_gym/{row['task']}", terminate_on_lost=False, **settings)
        try:
            agent = make(row["agent"], env, n_particles=max(row["particles"], 1), seed=first)
            for s in range(first, max(wanted) + 1):
                frames = []
                on_frame = (lambda f, i, frames=frames: frames.append(f)) if s in wanted else None
                result = run_episode(agent, env, s, None, on_frame=on_frame)
                if s in wanted:
                    out[s] = (result, frames)
        finally:
            env.close()
    for s, (result, _) in out.items():
        expected = np.asarray(recorded[s]["errors_mm"], dtype=np.float64)
        got = np.asarray(result.errors_mm, dtype=np.float64)
        if got.shape != expected.shape or not np.allclose(got, expected, rtol=1e-9, atol=1e-6):
            raise ReplayMismatch(
                f"{row['task']} {stats.cell_label(row)} seed {s}: the re-run's errors differ "
                f"from the recorded ones (mean {got.mean():.3f} vs {expected.mean():.3f} mm); "
                "were the environment settings (--data-dir, difficulty) the run's?"
            )
    return out


def _engine_episode() -> Callable[..., EpisodeResult] | None:
    try:
        from baselines import engine
    except ImportError:
        return None
    return getattr(engine, "run_cell_episode", None)


@contextmanager
def _quiet_stderr() -> Any:
    # OpenCV's FFmpeg backend prints a harmless tag warning for VP8 in WebM
    saved = os.dup(2)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(devnull)


def write_webm(path: Path, frames: Sequence[NDArray[np.uint8]], fps: float, scale: int = 2) -> Path:
    """Write RGB frames as a WebM (VP8) video, which browsers play.

    Raises:
        ValueError: If there are no frames.
        OSError: If OpenCV cannot write the file.
    """
    import cv2

    if not frames:
        raise ValueError("write_webm: no frames")
    big = [
        cv2.cvtColor(
            cv2.resize(f, None, fx=scale, fy=scale, interpolation=cv2.INTER_NEAREST),
            cv2.COLOR_RGB2BGR,
        )
        for f in frames
    ]
    h, w = big[0].shape[:2]
    with _quiet_stderr():
        writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"VP80"), float(fps), (w, h))
    if not writer.isOpened():
        raise OSError(f"{path}: OpenCV could not open a WebM (VP8) writer")
    try:
        for frame in big:
            writer.write(frame)
    finally:
        writer.release()
    return path


def _caption(frames: list[NDArray[np.uint8]], errors: Sequence[float]) -> list[NDArray[np.uint8]]:
    import cv2

    out = []
    for k, (frame, err) in enumerate(zip(frames, errors, strict=True)):
        img = np.ascontiguousarray(frame)
        cv2.putText(img, f"{k} {err:.0f}mm", (2, 10), cv2.FONT_HERSHEY_PLAIN, 0.7,
                    (255, 255, 0), 1, cv2.LINE_AA)  # fmt: skip
        out.append(img)
    return out


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text)


def write_videos(
    rows: Sequence[dict[str, Any]],
    folder: Path,
    env_kwargs: dict[str, Any] | None = None,
    cells: Callable[[dict[str, Any]], bool] | None = None,
    progress: bool = True,
) -> list[dict[str, Any]]:
    """Videos and contact sheets of each cell's best, median and worst episode.

    Returns:
        One dict per video: task, cell, choice, seed, mean_error_mm, video and
        sheet (paths relative to ``folder``).
    """
    import cv2
    from tqdm.auto import tqdm

    from humotion_gym.video import contact_sheet

    (folder / "videos").mkdir(parents=True, exist_ok=True)
    chosen = [r for r in rows if ran(r) and (cells is None or cells(r))]
    out = []
    for r in tqdm(chosen, desc="videos", disable=not progress):
        picks = choose_episodes(r)
        replayed = replay_episodes(r, sorted(set(picks.values())), env_kwargs)
        fps = float((env_kwargs or {}).get("fps", 30.0)) / int(
            (env_kwargs or {}).get("frame_skip", 1)
        )
        for choice, s in picks.items():
            result, frames = replayed[s]
            stem = _slug(f"{r['task']}_{stats.cell_label(r)}_{choice}_seed{s}")
            video = folder / "videos" / f"{stem}.webm"
            sheet = folder / "videos" / f"{stem}.jpg"
            if not video.exists():
                write_webm(video, _caption(frames, result.errors_mm), fps)
                # JPEG: the sensor noise makes a PNG of the sheet five times larger
                sheet_rgb = contact_sheet(frames, columns=6, count=12)
                image = cv2.cvtColor(sheet_rgb, cv2.COLOR_RGB2BGR)
                if not cv2.imwrite(str(sheet), image, [cv2.IMWRITE_JPEG_QUALITY, 90]):
                    raise OSError(f"{sheet}: could not write the contact sheet")
            out.append(
                {"task": r["task"], "cell": stats.cell_label(r), "choice": choice, "seed": s,
                 "mean_error_mm": result.mean_error_mm,
                 "video": video.relative_to(folder).as_posix(),
                 "sheet": sheet.relative_to(folder).as_posix()}
            )  # fmt: skip
    return out


# ------------------------------------------------------------------ HTML

_SORT_JS = """
document.querySelectorAll('table.sortable th').forEach(function (th, col) {
  th.addEventListener('click', function () {
    var table = th.closest('table'), body = table.tBodies[0];
    var rows = Array.prototype.slice.call(body.rows);
    var up = th.getAttribute('data-dir') !== 'up';
    table.querySelectorAll('th').forEach(function (h) { h.removeAttribute('data-dir'); });
    th.setAttribute('data-dir', up ? 'up' : 'down');
    function key(row) {
      var t = row.cells[th.cellIndex].textContent.trim();
      var n = parseFloat(t.replace(/,/g, ''));
      return isNaN(n) ? t.toLowerCase() : n;
    }
    rows.sort(function (a, b) {
      var x = key(a), y = key(b);
      var c = (typeof x === typeof y) ? (x < y ? -1 : x > y ? 1 : 0)
                                      : (typeof x === 'number' ? -1 : 1);
      return up ? c : -c;
    });
    rows.forEach(function (row) { body.appendChild(row); });
  });
});
// how many headers sort: a headless browser's DOM dump shows the script ran
document.body.setAttribute('data-sortable-headers',
                           document.querySelectorAll('table.sortable th').length);
"""

_CSS = """
body { font-family: sans-serif; margin: 1.5em; max-width: 1400px; }
table { border-collapse: collapse; margin: 0.5em 0 1.5em; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: left; }
th { background: #eee; cursor: pointer; user-select: none; }
th[data-dir=up]::after { content: ' \\25B2'; } th[data-dir=down]::after { content: ' \\25BC'; }
img.figure { max-width: 100%; border: 1px solid #ddd; }
.videos { display: flex; flex-wrap: wrap; gap: 1em; }
.videos figure { margin: 0; } .videos video { width: 256px; height: auto; }
.legend { color: #555; font-size: 0.85em; max-width: 60em; }
"""


def _html_table(table: list[list[str]], table_id: str) -> str:
    head = "".join(f"<th>{html.escape(c)}</th>" for c in table[0])
    body = "".join(
        "<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in row) + "</tr>" for row in table[1:]
    )
    return (
        f'<table class="sortable" id="{table_id}"><thead><tr>{head}</tr></thead>'
        f"<tbody>{body}</tbody></table>"
    )


def _leaderboard_table(rows: Sequence[dict[str, Any]]) -> list[list[str]]:
    """The Markdown leaderboard table parsed back into cells (the same columns)."""
    from baselines.leaderboard import markdown_table

    lines = markdown_table(rows).splitlines()
    return [[c.strip() for c in line.strip().strip("|").split("|")] for line in lines if
            not line.startswith("|---")]  # fmt: skip


def html_page(
    rows: Sequence[dict[str, Any]],
    computed: dict[str, Any],
    figures: dict[str, str],
    videos: Sequence[dict[str, Any]],
    notes: Sequence[str],
    title: str = "humotion_gym leaderboard",
    files: Sequence[str] = (),
) -> str:
    """The static ``index.html`` (inline CSS and JavaScript, links relative to its folder)."""
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>{html.escape(title)}</title><style>{_CSS}</style></head><body>",
        f"<h1>{html.escape(title)}</h1>",
        '<p>Files: <a href="tables.md">tables.md</a> (Markdown tables) &middot; '
        '<a href="stats.json">stats.json</a> (every statistic)'
        + "".join(f' &middot; <a href="{html.escape(f)}">{html.escape(f)}</a>' for f in files)
        + ". Click a column to sort.</p>",
    ]
    parts += [f'<p class="legend">{html.escape(n)}</p>' for n in notes]
    parts += ["<h2>Leaderboard</h2>", _html_table(_leaderboard_table(rows), "leaderboard")]
    parts += ["<h2>Cell statistics</h2>", _html_table(statistics_table(rows), "cells")]
    if computed["aggregate"]:
        parts += ["<h2>Across tasks (normalised by hold)</h2>"]
        parts += [_html_table(aggregate_table(computed["aggregate"]), "aggregate")]
        parts += [f'<p class="legend">{html.escape(SCORE_LEGEND)}</p>']
    if computed["pairwise"]:
        parts += ["<h2>Probability of improvement</h2>"]
        parts += [_html_table(improvement_table(computed["pairwise"]), "pairwise")]
    failures = failures_table(rows)
    if len(failures) > 1:
        parts += ["<h2>Cells that did not run</h2>", _html_table(failures, "failures")]
    if figures:
        parts += ["<h2>Figures</h2>"]
        for caption, src in figures.items():
            parts += [
                f'<h3>{html.escape(caption)}</h3><img class="figure" src="{html.escape(src)}" '
                f'alt="{html.escape(caption)}">'
            ]
    if videos:
        parts += [
            "<h2>Episodes</h2>",
            '<p class="legend">Each cell\'s best, median and worst episode by mean error, '
            "re-run with the estimate drawn over the frame (green wire figure); frame number "
            "and error in the corner. 'frames': a contact sheet of 12 frames.</p>",
        ]
        for (task, cell), group in _grouped(videos).items():
            parts += [f"<h3>{html.escape(task)} {html.escape(cell)}</h3>", '<div class="videos">']
            for v in group:
                label = f"{v['choice']}: seed {v['seed']}, {v['mean_error_mm']:.0f} mm"
                parts += [
                    f'<figure><video src="{html.escape(v["video"])}" controls loop muted '
                    'preload="metadata"></video>'
                    f"<figcaption>{html.escape(label)} &middot; "
                    f'<a href="{html.escape(v["sheet"])}">frames</a></figcaption></figure>'
                ]
            parts += ["</div>"]
    parts += [f"<script>{_SORT_JS}</script>", "</body></html>"]
    return "\n".join(parts)


def _grouped(videos: Sequence[dict[str, Any]]) -> dict[tuple[str, str], list[dict[str, Any]]]:
    out: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for v in videos:
        out.setdefault((v["task"], v["cell"]), []).append(v)
    return out


# ------------------------------------------------------------------ the report


def write_report(
    rows: Sequence[dict[str, Any]],
    folder: str | Path,
    *,
    videos: bool = False,
    env_kwargs: dict[str, Any] | None = None,
    video_cells: Callable[[dict[str, Any]], bool] | None = None,
    seed: int = 0,
    title: str = "humotion_gym leaderboard",
    progress: bool = True,
) -> Path:
    """Write the whole report of a leaderboard into ``folder``.

    Args:
        rows: The rows of :func:`baselines.leaderboard.run_leaderboard` (or
            :func:`load_rows`); rows with ``skipped`` or ``error`` are listed
            as cells that did not run.
        folder: The results folder (created if needed).
        videos: Also re-run each cell's best, median and worst episode and
            write their videos (costs up to one more run of each cell).
        env_kwargs: The environment settings of the run (needed for videos:
            ``data_dir`` and difficulty must be the run's to reproduce it).
        video_cells: Only cells for which this returns True get videos.
        seed: Seeds every bootstrap.
        title: The page's title.
        progress: Show a progress bar while making videos.

    Returns:
        The path of ``index.html``.

    Raises:
        ValueError: If no row ran.
        ReplayMismatch: If a video's episode does not reproduce its recorded errors.
    """
    if not any(ran(r) for r in rows):
        raise ValueError("rows: no cell ran (all skipped or failed); nothing to report")
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    computed = compute(rows, seed=seed)
    (folder / "stats.json").write_text(json.dumps(computed, indent=1, default=_plain))
    (folder / "tables.md").write_text(markdown_report(rows, computed))
    notes: list[str] = []
    figures: dict[str, str] = {}
    try:
        _pyplot()
    except ModuleNotFoundError:
        notes.append("No figures: matplotlib is not installed (pip install -e '.[plots]' adds it).")
    else:
        figures["Error over the episode's frames (mean, 95% bootstrap band)"] = (
            figure_error_over_frames(rows, folder / "error_over_frames.png", seed).name
        )
        figures["Still tracking (Kaplan-Meier, 95% band)"] = figure_survival(
            rows, folder / "survival.png"
        ).name
        figures["Interquartile mean per task (95% CI)"] = figure_iqm_per_task(
            rows, folder / "iqm_per_task.png", seed
        ).name
        if computed["aggregate"]:
            figures["Across tasks: normalised score and P(beats hold)"] = figure_aggregate(
                computed["aggregate"], folder / "aggregate.png"
            ).name
    made: list[dict[str, Any]] = []
    if videos:
        made = write_videos(rows, folder, env_kwargs, video_cells, progress)
        (folder / "videos.json").write_text(json.dumps(made, indent=1))
    index = folder / "index.html"
    # the engine's files of the same results folder, where they are
    files = [f for f in ("results.json", "table.md", "episodes.jsonl") if (folder / f).is_file()]
    index.write_text(html_page(rows, computed, figures, made, notes, title, files))
    return index


def _plain(value: Any) -> Any:
    if hasattr(value, "tolist"):
        return value.tolist()
    raise TypeError(f"not JSON-serialisable: {type(value).__name__}")
