"""The report's videos: each cell's best, median and worst episode, re-run and drawn.

Each chosen episode is re-run with rendering (the estimate drawn over the
frame) by :func:`baselines.leaderboard.engine.run_cell_episode`, and must
reproduce its recorded errors (:class:`ReplayMismatch`); it is written as a
WebM (VP8, which browsers play) with a contact sheet (JPEG).
"""

from __future__ import annotations

import contextlib
import json
import os
import re
from collections.abc import Callable, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray
from tqdm.auto import tqdm

from baselines.leaderboard.engine import run_cell_episode
from baselines.leaderboard.evaluation import EpisodeResult
from baselines.leaderboard.rows import cell_label, ran
from humotion_gym.files import write_atomically
from humotion_gym.video import contact_sheet

#: How far a replay's per-frame error may be from the recorded one: compact
#: results keep whole millimetres (:data:`baselines.leaderboard.results.SERIES_KEYS`),
#: some rounded from a tenth first: half of one plus half a tenth, and the float's rounding.
SERIES_ATOL_MM = 0.55 + 1e-6
#: How far a replay's mean error may be from the recorded one, relatively.
MEAN_RTOL = 1e-5


class ReplayMismatch(RuntimeError):
    """A re-run episode did not reproduce the errors recorded for it."""


def first_agent_seed(row: dict[str, Any]) -> list[dict[str, Any]]:
    """The row's episodes of its first agent seed (all of them where none is recorded)."""
    episodes = list(row["episodes"])
    seeds = [e["agent_seed"] for e in episodes if "agent_seed" in e]
    if not seeds:
        return episodes
    first = min(seeds)
    return [e for e in episodes if e.get("agent_seed") == first]


def choose_episodes(row: dict[str, Any]) -> dict[str, int]:
    """The seeds of a cell's best, median and worst episode by mean error.

    Of its first agent seed's episodes; the median is the lower middle, ties go
    to the smaller seed, and choices may share a seed.
    """
    ranked = sorted(first_agent_seed(row), key=lambda e: (e["mean_error_mm"], e["seed"]))
    return {
        "best": int(ranked[0]["seed"]),
        "median": int(ranked[(len(ranked) - 1) // 2]["seed"]),
        "worst": int(ranked[-1]["seed"]),
    }


def replay_episodes(
    row: dict[str, Any],
    seeds: Sequence[int],
    env_kwargs: dict[str, Any] | None = None,
    declared: bool = False,
) -> dict[int, tuple[EpisodeResult, list[NDArray[np.uint8]]]]:
    """Re-run a cell's episodes with rendering; check they reproduce the recorded errors.

    Each of ``seeds`` (of the row's first agent seed) is re-run on its own with
    :func:`~baselines.leaderboard.engine.run_cell_episode` on the run's
    ``env_kwargs``, its agent seeded as the run seeded it; with ``declared``
    (the run scored the declared episodes) on its recorded clip and start frame.

    Returns:
        ``{seed: (result, frames)}``; each frame is the rendered frame with
        the estimate drawn over it.

    Raises:
        ValueError: If a seed is not one of the row's episodes.
        ReplayMismatch: If a re-run's errors differ from the recorded ones.
    """
    recorded = {int(e["seed"]): e for e in first_agent_seed(row)}
    missing = [s for s in seeds if s not in recorded]
    if missing:
        raise ValueError(f"seeds: {missing} are not episodes of {cell_label(row)}")
    first = min(recorded)
    settings = {**(env_kwargs or {}), "render_mode": "rgb_array"}
    out: dict[int, tuple[EpisodeResult, list[NDArray[np.uint8]]]] = {}
    for s in sorted(set(int(s) for s in seeds)):
        episode = recorded[s]
        window = (str(episode["clip_id"]), int(episode["start_frame"])) if declared else None
        frames: list[NDArray[np.uint8]] = []
        result = run_cell_episode(
            row["task"], row["agent"], row["particles"], s, int(episode.get("agent_seed", first)),
            settings, on_frame=lambda f, i, frames=frames: frames.append(f), window=window,
        )  # fmt: skip
        out[s] = (result, frames)
    for s, (result, _) in out.items():
        got = np.asarray(result.errors_mm, dtype=np.float64)
        same = True  # a record kept without its series is checked by its mean alone
        if recorded[s].get("errors_mm"):
            expected = np.asarray(recorded[s]["errors_mm"], dtype=np.float64)
            same = got.shape == expected.shape and np.allclose(
                got, expected, rtol=1e-6, atol=SERIES_ATOL_MM
            )
        mean = float(recorded[s]["mean_error_mm"])
        if not (same and np.isclose(float(got.mean()), mean, rtol=MEAN_RTOL, atol=1e-6)):
            raise ReplayMismatch(
                f"{row['task']} {cell_label(row)} seed {s}: the re-run's errors differ "
                f"from the recorded ones (mean {got.mean():.3f} vs {mean:.3f} mm); "
                "were the environment settings (--data-dir, difficulty) the run's?"
            )
    return out


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

    def write(tmp: Path) -> None:
        with _quiet_stderr():
            writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter.fourcc(*"VP80"), float(fps), (w, h))
        if not writer.isOpened():
            raise OSError(f"{path}: OpenCV could not open a WebM (VP8) writer")
        try:
            for frame in big:
                writer.write(frame)
        finally:
            writer.release()

    # Whole or not at all: a report reuses the videos it finds beside its videos.json.
    write_atomically(path, write, keep_suffix=True)
    return path


def _write_jpeg(tmp: Path, image: NDArray[np.uint8], path: Path) -> None:
    """Write a BGR image as JPEG (quality 90) to ``tmp``, where ``path`` is written."""
    if not cv2.imwrite(str(tmp), image, [cv2.IMWRITE_JPEG_QUALITY, 90]):
        raise OSError(f"{path}: could not write the contact sheet")


def _caption(frames: list[NDArray[np.uint8]], errors: Sequence[float]) -> list[NDArray[np.uint8]]:
    out = []
    for k, (frame, err) in enumerate(zip(frames, errors, strict=True)):
        img = np.ascontiguousarray(frame)
        cv2.putText(img, f"{k} {err:.0f}mm", (2, 10), cv2.FONT_HERSHEY_PLAIN, 0.7,
                    (255, 255, 0), 1, cv2.LINE_AA)  # fmt: skip
        out.append(img)
    return out


def file_slug(text: str) -> str:
    """``text`` as a file name: each run of other characters than ``A-Za-z0-9_.-`` one ``_``."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text)


def write_videos(
    rows: Sequence[dict[str, Any]],
    folder: Path,
    env_kwargs: dict[str, Any] | None = None,
    cells: Callable[[dict[str, Any]], bool] | None = None,
    progress: bool = True,
    declared: bool = False,
) -> list[dict[str, Any]]:
    """Videos and contact sheets of each cell's best, median and worst episode.

    ``declared``: the run scored the declared episodes (see :func:`replay_episodes`).
    A video an earlier report left in ``folder`` is kept only where its
    ``videos.json`` entry is this one's (the same episode, the same error).

    Returns:
        One dict per video: task, cell, choice, seed, mean_error_mm, video and
        sheet (paths relative to ``folder``).
    """
    earlier = {e.get("video"): e for e in earlier_videos(folder)}
    (folder / "videos").mkdir(parents=True, exist_ok=True)
    chosen = [r for r in rows if ran(r) and (cells is None or cells(r))]
    settings = env_kwargs or {}
    out = []
    for r in tqdm(chosen, desc="videos", disable=not progress):
        picks = choose_episodes(r)
        replayed = replay_episodes(r, sorted(set(picks.values())), env_kwargs, declared)
        fps = float(settings.get("fps", 30.0)) / int(settings.get("frame_skip", 1))
        for choice, s in picks.items():
            result, frames = replayed[s]
            stem = file_slug(f"{r['task']}_{cell_label(r)}_{choice}_seed{s}")
            video = folder / "videos" / f"{stem}.webm"
            sheet = folder / "videos" / f"{stem}.jpg"
            entry = {"task": r["task"], "cell": cell_label(r), "choice": choice, "seed": s,
                     "mean_error_mm": result.mean_error_mm,
                     "video": video.relative_to(folder).as_posix(),
                     "sheet": sheet.relative_to(folder).as_posix()}  # fmt: skip
            if earlier.get(entry["video"]) != entry or not (video.exists() and sheet.exists()):
                write_webm(video, _caption(frames, result.errors_mm), fps)
                # JPEG: the sensor noise makes a PNG of the sheet five times larger
                sheet_rgb = contact_sheet(frames, columns=6, count=12)
                image = cv2.cvtColor(sheet_rgb, cv2.COLOR_RGB2BGR)
                write_atomically(
                    sheet, lambda tmp, i=image, s=sheet: _write_jpeg(tmp, i, s), keep_suffix=True
                )
            out.append(entry)
    return out


def earlier_videos(folder: Path) -> list[dict[str, Any]]:
    """The entries of the ``videos.json`` an earlier report left in ``folder`` (or none)."""
    try:
        entries = json.loads((folder / "videos.json").read_text())
    except (OSError, ValueError):
        return []
    return [e for e in entries if isinstance(e, dict)] if isinstance(entries, list) else []


def remove_earlier_videos(folder: Path) -> None:
    """Delete the videos and sheets an earlier report listed, and its ``videos.json``."""
    for entry in earlier_videos(folder):
        for key in ("video", "sheet"):
            name = entry.get(key)
            if isinstance(name, str) and name.startswith("videos/") and ".." not in name:
                (folder / name).unlink(missing_ok=True)
    (folder / "videos.json").unlink(missing_ok=True)
    with contextlib.suppress(OSError):  # only if nothing else is left in it
        (folder / "videos").rmdir()
