"""The declared test episodes: a fixed list of windows per task and data source.

The benchmark's test set is a list, not a draw, written down once and shipped
with the package (``humotion_gym/envs/episodes/{Task}.json``), one list per data
source: ``"cmu"`` (the CMU test persons of the real motion capture) and
``"synthetic"`` (the built-in library's test subjects, so the leaderboard runs
without downloads). The list is what :func:`make_windows` gives, a pure function
of the task spec, the library's test clips and :data:`PER_CLIP`; :data:`MADE`
states the rule (docs/protocol.md, "The declared test list"). Each window carries
its clip's frame count: :func:`check_windows` refuses a library whose clips differ.

Rebuild the files (the synthetic lists always, the CMU lists from the shared
motion capture), or check them against the rule without writing::

    python -m humotion_gym.envs.episodes --write --data-dir ../shared/mocap
    python -m humotion_gym.envs.episodes --check --data-dir ../shared/mocap
"""

from __future__ import annotations

import argparse
import functools
import json
import re
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass
from importlib import resources
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from humotion_gym.envs.tasks import VIEW_VARIANTS, TaskSpec, get_task
from humotion_gym.files import write_text_atomically
from humotion_gym.mocap.library import MotionLibrary, default_library, synthetic_library
from humotion_gym.mocap.motion import Motion, observed_starts

#: Format version of the files.
VERSION = 2
#: The data sources a list exists for.
SOURCES: tuple[str, ...] = ("cmu", "synthetic")
#: At most this many windows per clip, by task base name: about 35 episodes
#: for ArmTrack and BodyTrack on either source; every window the walking clips
#: hold up to about 20 for WalkTrack and SideWalk.
PER_CLIP: dict[str, int] = {"ArmTrack": 3, "BodyTrack": 3, "WalkTrack": 8, "SideWalk": 8}
#: Frame skip the windows are cut for (the environments' default).
FRAME_SKIP = 1
#: The package folder of the files.
_FOLDER = "episodes"

MADE = (
    "Cut by humotion_gym.envs.episodes.make_windows from the test split of the {source} "
    "library at 30 Hz: in every test clip whose label the task takes (TaskSpec.labels) and "
    "which holds one window of {span} frames (episode_frames {frames} x frame_skip 1, plus "
    "the initial frame), windows in which every frame is observed, no two sharing a frame, "
    "at most {per_clip} per clip, spread evenly across the clip (each placed at the observed "
    "start nearest to its evenly spaced target that leaves room for the rest); every "
    "qualifying clip has at least one. Nothing about any agent's results was used, and no "
    "start was dropped for little motion (TaskSpec.min_motion_mm, which ArmTrack-v1 applies "
    "to its random starts, is not applied here). 'frames' is the clip's frame count, a "
    "fingerprint checked by check_windows. Rebuilt by `python -m humotion_gym.envs.episodes "
    "--write --data-dir /work/shared/mocap`."
)


@dataclass(frozen=True)
class EpisodeWindow:
    """One declared test episode: a window of one clip.

    Attributes:
        clip_id: The clip (``"cmu/02_05"``).
        person: Who performs it (``"cmu-02"``; the subject for synthetic clips).
        start: First frame of the window (the episode's initial frame).
        frames: The clip's frame count, a fingerprint of the clip.
    """

    clip_id: str
    person: str
    start: int
    frames: int


def task_base(task: str) -> str:
    """A task's name without namespace or version: ``"humotion_gym/ArmTrack-v2"``: ``"ArmTrack"``.

    Raises:
        KeyError: If no registered task has that base name.
    """
    name = task.split("/")[-1].split(":")[-1]
    # a multi-view id shows its task's episodes
    base = VIEW_VARIANTS[name][0] if name in VIEW_VARIANTS else name
    base = base.split("-v")[0]
    if base not in PER_CLIP:
        raise KeyError(f"task: unknown task {task!r}; the tasks are {sorted(PER_CLIP)}")
    return base


def task_spec(task: str) -> TaskSpec:
    """The spec a task's list is cut for: the latest version of its base name."""
    return get_task(task_base(task))  # a family's name is its current version


def window_frames(spec: TaskSpec, frame_skip: int = FRAME_SKIP) -> int:
    """Frames one episode covers: ``episode_frames * frame_skip + 1`` (the initial frame too)."""
    return spec.episode_frames * frame_skip + 1


def person_of(motion: Motion) -> str:
    """The person of a clip: its ``meta["person"]``, else its subject."""
    return motion.meta.get("person") or motion.subject


def spread_starts(good: NDArray[np.intp], span: int, per_clip: int) -> list[int]:
    """Up to ``per_clip`` starts from ``good``, windows disjoint, spread evenly.

    As many windows as fit (at most ``per_clip``): the most disjoint windows
    among ``good`` is what taking the earliest that fits after the last gives
    (windows of equal length). Window ``i`` of ``k`` then aims at the start
    ``i / (k - 1)`` of the way from the first good start to the last (the
    middle for one) and takes the good start nearest to it (the earlier on a
    tie) among those after the previous window and no later than the latest
    start that leaves room for the windows still to come.

    Args:
        good: Sorted starts whose windows qualify.
        span: Frames per window.
        per_clip: Most windows to take.
    """
    if good.size == 0 or per_clip < 1:
        return []
    most = 0
    next_free = -1
    for s in good.tolist():
        if s >= next_free:
            most, next_free = most + 1, s + span
    k = min(per_clip, most)
    # latest[i]: the latest start window i may take so that k - 1 - i still fit after it
    latest = [int(good[-1])] * k
    for i in range(k - 2, -1, -1):
        latest[i] = int(good[np.searchsorted(good, latest[i + 1] - span, side="right") - 1])
    lo, hi = float(good[0]), float(good[-1])
    targets = [(lo + hi) / 2.0] if k == 1 else np.linspace(lo, hi, k).tolist()
    chosen: list[int] = []
    for i, target in enumerate(targets):
        floor = chosen[-1] + span if chosen else int(good[0])
        pool = good[(good >= floor) & (good <= latest[i])]
        chosen.append(int(pool[np.argmin(np.abs(pool - target))]))
    return chosen


def qualifying_clips(spec: TaskSpec, library: MotionLibrary) -> list[Motion]:
    """The test clips a task's list covers: the task's labels, one observed window at least."""
    span = window_frames(spec)
    clips = library.split("test").filter(labels=spec.labels, min_frames=span)
    return [m for m in clips if observed_starts(m, span).size]


def make_windows(spec: TaskSpec, library: MotionLibrary, per_clip: int) -> list[EpisodeWindow]:
    """The rule: a task's declared windows on a library's test clips (:data:`MADE`).

    Args:
        spec: The task.
        library: A library; only its test split is read.
        per_clip: At most this many windows per clip.

    Returns:
        The windows, clips sorted by id, starts increasing within a clip.
    """
    span = window_frames(spec)
    out = []
    for m in sorted(qualifying_clips(spec, library), key=lambda m: m.clip_id):
        for start in spread_starts(observed_starts(m, span), span, per_clip):
            out.append(EpisodeWindow(m.clip_id, person_of(m), start, m.n_frames))
    return out


def source_of(library: MotionLibrary) -> str:
    """Which declared list a library's test clips take: ``"cmu"`` or ``"synthetic"``.

    Raises:
        ValueError: If the test clips are of neither, or of several data sets.
    """
    test = library.split("test")
    datasets = sorted({"synthetic" if m.synthetic else m.dataset for m in test})
    if len(datasets) == 1 and datasets[0] in SOURCES:
        return datasets[0]
    raise ValueError(
        f"library: expected test clips all from one of {list(SOURCES)}, found data sets "
        f"{datasets or '(no test clips)'} in {len(test)} test clips"
    )


def check_windows(windows: Iterable[EpisodeWindow], library: MotionLibrary, span: int = 1) -> None:
    """Check that a list's windows are clips of this library, where the list says.

    Args:
        windows: The declared windows.
        library: The library the episodes will be cut from.
        span: Frames per window (:func:`window_frames`); 1 checks the starts only.

    Raises:
        ValueError: Naming the clip, if a clip is missing from the library, has
            another frame count than the list's fingerprint, shows another
            person than the list names or one the library does not hold out,
            or a window does not lie within it.
    """
    clips = {m.clip_id: m for m in library}
    for w in windows:
        m = clips.get(w.clip_id)
        if m is None:
            raise ValueError(
                f"declared clip {w.clip_id!r} is not in the library ({len(clips)} clips)"
            )
        if m.n_frames != w.frames:
            raise ValueError(
                f"declared clip {w.clip_id!r}: expected {w.frames} frames, the library's has "
                f"{m.n_frames} (another version or frame rate of the clip)"
            )
        if m.subject != w.person or m.subject not in library.held_out:
            # a declared window is a test episode: of the person it names, held out
            raise ValueError(
                f"declared clip {w.clip_id!r} shows {m.subject!r} (the list says "
                f"{w.person!r}), {'a' if m.subject in library.held_out else 'not a'} held-out "
                "person of this library: declared episodes are test episodes"
            )
        if not 0 <= w.start <= m.n_frames - span:
            raise ValueError(
                f"declared clip {w.clip_id!r}: window {w.start}..{w.start + span - 1} lies "
                f"outside its {m.n_frames} frames"
            )


def _path(base: str) -> Path:
    return Path(
        str(resources.files("humotion_gym.envs").joinpath(_FOLDER).joinpath(f"{base}.json"))
    )


@functools.cache
def _load(base: str) -> dict:
    path = _path(base)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError as exc:
        raise FileNotFoundError(f"{path}: no declared episodes for {base}") from exc
    if doc.get("task") != base or doc.get("version") != VERSION:
        raise ValueError(
            f"{path}: expected task {base!r} version {VERSION}, "
            f"got {doc.get('task')!r} version {doc.get('version')!r}"
        )
    return doc


def declared_episodes(task: str, source: str) -> tuple[EpisodeWindow, ...]:
    """A task's declared test episodes on a data source.

    Args:
        task: ``"ArmTrack"``, ``"ArmTrack-v1"``, ``"humotion_gym/ArmTrack-v2"``...
        source: ``"cmu"`` or ``"synthetic"`` (:func:`source_of`).

    Raises:
        KeyError: If the task or source is unknown.
    """
    base = task_base(task)
    data = _load(base)["data"]
    if source not in data:
        raise KeyError(f"source: expected one of {sorted(data)} for {base}, got {source!r}")
    return tuple(EpisodeWindow(**w) for w in data[source])


def _document(base: str, lists: dict[str, list[EpisodeWindow]]) -> dict:
    spec = task_spec(base)
    made = MADE.format(
        source="CMU (test persons) and synthetic (test subjects)",
        span=window_frames(spec), frames=spec.episode_frames, per_clip=PER_CLIP[base],
    )  # fmt: skip
    return {
        "task": base,
        "version": VERSION,
        "made": made,
        "data": {s: [asdict(w) for w in ws] for s, ws in lists.items()},
    }


def _dumps(doc: dict) -> str:
    """The file's text: one window a line, so a change to the list reads as a diff."""
    text = json.dumps(doc, indent=1)
    window = re.compile(r"\{\n\s*(\"clip_id\"[^}]*?)\n\s*\}")
    return window.sub(lambda m: "{" + re.sub(r"\n\s*", " ", m[1]) + "}", text) + "\n"


def rule_lists(libraries: dict[str, MotionLibrary]) -> dict[str, dict[str, list[EpisodeWindow]]]:
    """Every task's windows on each source's library: ``{task base: {source: windows}}``."""
    return {
        base: {
            s: make_windows(task_spec(base), lib, PER_CLIP[base]) for s, lib in libraries.items()
        }
        for base in PER_CLIP
    }


def sizes(windows: Sequence[EpisodeWindow]) -> tuple[int, int, int]:
    """``(windows, clips, persons)`` of a list."""
    return len(windows), len({w.clip_id for w in windows}), len({w.person for w in windows})


def main(argv: Sequence[str] | None = None) -> int:
    """Write (``--write``) or check (``--check``) the shipped files against the rule.

    The synthetic lists always; the CMU lists when ``--data-dir`` is given
    (else the files' CMU lists are kept as they are, and not checked).
    """
    parser = argparse.ArgumentParser(prog="python -m humotion_gym.envs.episodes")
    action = parser.add_mutually_exclusive_group(required=True)
    action.add_argument("--write", action="store_true", help="rewrite the files")
    action.add_argument("--check", action="store_true", help="compare the files with the rule")
    parser.add_argument("--data-dir", help="the real motion capture (its CMU test persons)")
    args = parser.parse_args(argv)
    libraries = {"synthetic": synthetic_library()}
    if args.data_dir:
        real = default_library(args.data_dir, progress=False)
        libraries["cmu"] = real
        if source_of(real) != "cmu":  # pragma: no cover - source_of raises first
            raise ValueError(f"--data-dir: expected CMU test persons in {args.data_dir}")
    differ = []
    for base, lists in rule_lists(libraries).items():
        path = _path(base)
        old = json.loads(path.read_text(encoding="utf-8")) if path.exists() else {"data": {}}
        if args.check:
            differ += [f"{base}/{s}" for s, ws in lists.items()
                       if old["data"].get(s) != [asdict(w) for w in ws]]  # fmt: skip
        else:
            merged = {s: [EpisodeWindow(**w) for w in old["data"].get(s, [])] for s in SOURCES}
            merged.update(lists)
            write_text_atomically(path, _dumps(_document(base, merged)))
        for s, ws in lists.items():
            n, clips, persons = sizes(ws)
            print(f"{base:10s} {s:10s} {n:3d} windows {clips:3d} clips {persons:2d} persons")
    _load.cache_clear()
    if differ:
        print(f"differ from the rule: {', '.join(differ)}")
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
