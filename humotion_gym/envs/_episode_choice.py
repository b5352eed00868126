"""How an environment picks its episodes: reset options, the split's persons, start frames.

:class:`EpisodeChoice` is a part of
:class:`~humotion_gym.envs.pose_tracking.PoseTrackingEnv`: it checks a
reset's options, refuses a clip of a person the split must not show, and
draws the clip and start frame.
"""

from __future__ import annotations

import os
import weakref
from collections import OrderedDict
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from humotion_gym.body import KEYPOINT_INDEX, N_KEYPOINTS
from humotion_gym.checks import is_integer
from humotion_gym.envs.tasks import env_id
from humotion_gym.kinematics import batch_pose_geometry
from humotion_gym.mocap.library import MotionLibrary, load_library
from humotion_gym.mocap.motion import Motion, observed_starts
from humotion_gym.mocap.persons import same_skeleton, skeleton_signature

FloatArray = NDArray[np.float64]

#: The keys ``reset(options=...)`` understands.
RESET_OPTIONS: tuple[str, ...] = ("clip_id", "file", "motion", "start")

# Keypoints and cone axes of every frame of the clips episodes were drawn from,
# computed once per clip and shared by every environment of the process; the
# least recently used clips go beyond _CLIP_GEOMETRY_FRAMES frames.
_CLIP_GEOMETRY: OrderedDict[int, tuple[weakref.ref[Motion], FloatArray]] = OrderedDict()
_CLIP_GEOMETRY_FRAMES = 60_000


def clip_geometry(motion: Motion) -> FloatArray:
    """``(T, 35, 3)`` :func:`batch_pose_geometry` of a clip's frames (cached)."""
    key = id(motion)
    entry = _CLIP_GEOMETRY.get(key)
    if entry is not None and entry[0]() is motion:
        _CLIP_GEOMETRY.move_to_end(key)
        return entry[1]
    geometry = batch_pose_geometry(motion.params, motion.shape)
    _CLIP_GEOMETRY[key] = (weakref.ref(motion), geometry)
    total = sum(g.shape[0] for _, g in _CLIP_GEOMETRY.values())
    while total > _CLIP_GEOMETRY_FRAMES and len(_CLIP_GEOMETRY) > 1:
        _, (_, dropped) = _CLIP_GEOMETRY.popitem(last=False)
        total -= dropped.shape[0]
    return geometry


#: The clips not its library's whose good starts an environment remembers.
STARTS_EXTRA = 64


def _check_file_option(file: Any) -> None:
    """Refuse a ``file`` option that is no ``.bvh`` or ``.amc`` file.

    Raises:
        FileNotFoundError: If it names a motion file that does not exist (as
            a missing ``data_dir`` or :func:`~humotion_gym.mocap.bvh.load_bvh`).
        ValueError: If it is no path, names another kind of file, or a folder.
    """
    wanted = "reset: options['file'] must be the path of one .bvh or .amc file"
    path = os.fspath(file) if isinstance(file, str | os.PathLike) else None
    if not isinstance(path, str) or Path(path).suffix.lower() not in (".bvh", ".amc"):
        raise ValueError(f"{wanted}, got {file!r}")
    if not Path(path).exists():
        raise FileNotFoundError(f"reset: options['file'] {path}: no such file")
    if not Path(path).is_file():
        raise ValueError(f"{wanted}, got the folder {path!r}")


class TooFewFrames(ValueError):
    """No clip of the split holds an episode of the frames asked for.

    A ``ValueError`` whose message says so; ``longest`` (the longest such
    clip's frames) lets a command name its own flag and bound.
    """

    def __init__(self, message: str, longest: int) -> None:
        super().__init__(message)
        self.longest = longest


class EpisodeChoice:
    """The episode-choosing part of the tracking environment (see the module docstring).

    The environment provides the attributes annotated below.
    """

    library: MotionLibrary
    split: str
    clips: MotionLibrary
    episode_frames: int
    frame_skip: int
    _starts: dict[str, tuple[Motion, NDArray[np.intp]]]
    _own_clips: dict[str, Motion]  # the library's clips by id
    _unseen_cache: list[tuple[str, FloatArray]] | None
    _err_kp: NDArray[np.intp]
    task: Any
    np_random: np.random.Generator

    def _episode_clips(self) -> MotionLibrary:
        """The split's clips an episode can be drawn from: the task's labels, long enough.

        Raises:
            TooFewFrames: If no clip of the task's labels is long enough.
            ValueError: If no clip qualifies for another reason (the message says why).
        """
        library, split, name = self.library, self.split, env_id(self.task)
        in_split = library.episode_split(split)
        if len(in_split) == 0:
            persons = sorted({m.subject for m in library})
            shown = ", ".join(persons[:5]) + (" ..." if len(persons) > 5 else "")
            # what the data lacks, and no advice: the same words reach the Python
            # API and commands with other flags
            raise ValueError(
                f"{name}: the data holds no {split} person's clip: its {len(library)} "
                f"clips show {shown} (see humotion-gym data persons); {split} episodes "
                f"show {split} persons only"
            )
        labels = self.task.labels
        labelled = in_split.filter(labels=labels)
        need = self.episode_frames * self.frame_skip + 1
        clips = labelled.filter(min_frames=need)
        if len(labelled) == 0 and labels is not None:  # the label rules them out
            found = sorted({m.label for m in in_split})
            raise ValueError(
                f"{name}: no {split} clip is labelled {' or '.join(labels)} "
                f"(its {len(in_split)} {split} clips are labelled {', '.join(found)}; a user's "
                "clip takes its label from its file name: see humotion-gym data info)"
            )
        if len(clips) == 0:
            which = "any label" if labels is None else f"label {' or '.join(labels)}"
            longest = max(m.n_frames for m in labelled)
            raise TooFewFrames(
                f"{name}: no {split} clip of {which} holds {need} frames "
                f"({self.episode_frames} frames, every {self.frame_skip}, and the frame "
                f"before); the longest has {longest} ({len(library)} clips in the library)",
                longest,
            )
        if self.task.min_motion_mm > 0:
            # only clips with at least one start that moves enough
            clips = MotionLibrary(
                tuple(m for m in clips if self._good_starts(m).size), clips.test_subjects
            )
            if len(clips) == 0:
                raise ValueError(
                    f"{name}: no {split} clip moves its {list(self.task.error_keypoints)} "
                    f"by {self.task.min_motion_mm:g} mm within an episode"
                )
        return clips

    def _check_options(self, options: dict[str, Any] | None) -> dict[str, Any]:
        """The reset options, refused with a clear ``ValueError`` when wrong."""
        if options is None:
            return {}
        if not isinstance(options, dict):
            raise ValueError(f"reset: options must be a dict, got {type(options).__name__}")
        unknown = sorted(set(options) - set(RESET_OPTIONS))
        if unknown:
            raise ValueError(
                f"reset: unknown options {unknown}; the options are {list(RESET_OPTIONS)}"
            )
        chosen = [k for k in ("clip_id", "file", "motion") if k in options]
        if len(chosen) > 1:
            raise ValueError(f"reset: give at most one of clip_id, file, motion; got {chosen}")
        if "motion" in options:
            self._check_motion_option(options["motion"])
        if "file" in options:
            _check_file_option(options["file"])
        if "clip_id" in options:
            clip_id = options["clip_id"]
            if not isinstance(clip_id, str) or clip_id not in self.library.clip_ids:
                ids = self.library.clip_ids
                raise ValueError(
                    f"reset: options['clip_id'] {clip_id!r} is not in the library; its "
                    f"{len(ids)} clips include {ids[:8]}"
                )
        if "start" in options:
            start = options["start"]
            if not is_integer(start):
                raise ValueError(f"reset: options['start'] must be an integer frame, got {start!r}")
        return dict(options)

    def _check_motion_option(self, motion: Any) -> None:
        """Refuse a ``motion`` option that is no :class:`Motion` or runs at another rate."""
        if not isinstance(motion, Motion):
            raise ValueError(
                "reset: options['motion'] must be a humotion_gym Motion, got "
                f"{type(motion).__name__}"
            )
        fps = float(self.library[0].fps) if len(self.library) else motion.fps
        if float(motion.fps) != fps:
            raise ValueError(
                f"reset: options['motion'] {motion.clip_id!r} is at {motion.fps:g} Hz, the "
                f"environment's clips at {fps:g} Hz (load it with fps={fps:g})"
            )

    def _pick_clip(self, options: dict[str, Any]) -> Motion:
        if "motion" in options:
            return self._check_person(options["motion"], "motion")
        if "clip_id" in options:
            return self._check_person(self.library[options["clip_id"]], "clip_id")
        if "file" in options:
            # one motion file (checked in _check_options) is one clip
            lib = load_library([options["file"]], fps=self.library[0].fps, progress=False)
            return self._check_person(lib[0], "file")
        return self.clips[int(self.np_random.integers(len(self.clips)))]

    def _check_person(self, motion: Motion, option: str) -> Motion:
        """``motion``, refused where it shows a person this split must not show.

        By name and by skeleton (:func:`~humotion_gym.mocap.persons.same_skeleton`
        against each such person of the library: a held-out person's file under
        another name is still that person); a clip from outside the library also
        by its own split (``meta``, from its data set's rule).

        Raises:
            ValueError: Naming the option, the clip and the person.
        """
        if self.split != "test" and motion.meta.get("split") == "test":
            raise ValueError(
                f"reset: options[{option!r}] {motion.clip_id!r} shows "
                f"{motion.meta.get('person', motion.subject)!r}, a held-out person by its data "
                f"set's rule ({motion.meta.get('split_rule', 'unnamed')}); a split={self.split!r} "
                "environment never shows held-out persons (make it with split='test')"
            )
        unseen = self.library.unseen_by(self.split)
        if not unseen:
            return motion
        # the person shown: by name, else the unseen person of the same skeleton,
        # whose split (not the clip's own name's) is the one to advise
        shown, person = motion.subject, motion.subject
        if shown not in unseen:
            signature = skeleton_signature(motion)
            for other, other_signature in self._unseen_signatures():
                if same_skeleton(signature, other_signature):
                    shown, person = other, f"{other} (same skeleton as {motion.subject!r})"
                    break
            else:
                return motion
        showing = "test" if shown in self.library.held_out else "validation"
        raise ValueError(
            f"reset: options[{option!r}] {motion.clip_id!r} shows {person}, a held-out person; "
            f"a split={self.split!r} environment never shows the persons {sorted(unseen)} "
            f"(make it with split={showing!r})"
        )

    def _unseen_signatures(self) -> list[tuple[str, FloatArray]]:
        """A skeleton signature of each person of the library this split must not show."""
        cached = self._unseen_cache
        if cached is None:
            unseen = self.library.unseen_by(self.split)
            first: dict[str, Motion] = {}
            for m in self.library:
                if m.subject in unseen:
                    first.setdefault(m.subject, m)
            cached = [(name, skeleton_signature(m)) for name, m in sorted(first.items())]
            self._unseen_cache = cached
        return cached

    def _pick_start(self, motion: Motion, options: dict[str, Any]) -> int:
        span = self.episode_frames * self.frame_skip
        if motion.n_frames <= span:
            raise ValueError(
                f"{motion.clip_id}: {motion.n_frames} frames, an episode needs {span + 1}"
            )
        if "start" in options:
            start = int(options["start"])
            if not 0 <= start < motion.n_frames - span:
                drawn = (
                    ""
                    if options.keys() & {"clip_id", "file", "motion"}
                    else ("; without clip_id the clip is drawn at random, so give it too")
                )
                raise ValueError(
                    f"reset: options['start'] must be in [0, {motion.n_frames - span}) for "
                    f"{motion.clip_id} ({motion.n_frames} frames, an episode spans {span + 1})"
                    f"{drawn}"
                )
            return start
        good = self._good_starts(motion)
        if good.size == 0:
            good = np.arange(motion.n_frames - span)
        return int(good[self.np_random.integers(good.size)])

    def _good_starts(self, motion: Motion) -> NDArray[np.intp]:
        """Start frames whose episode was observed throughout and moves enough.

        A start is good when every frame of its episode was observed and, for a
        task with ``min_motion_mm``, its scored keypoints (relative to the
        task's anchor) move at least that far within the episode. Selection
        only: what a start's episode shows is still a function of its frames.
        Cached per clip.
        """
        cached = self._starts.get(motion.clip_id)
        if cached is not None and cached[0] is motion:
            return cached[1]
        good = observed_starts(motion, self.episode_frames * self.frame_skip + 1)
        if self.task.min_motion_mm > 0 and good.size:
            good = good[self._episode_motion(motion)[good] >= self.task.min_motion_mm]
        # The library's clips, and at most STARTS_EXTRA others, the oldest going
        # first: a long run of reset(options={"motion": ...}) keeps only the
        # last STARTS_EXTRA given clips alive, not every one.
        own = self._own_clips
        if own.get(motion.clip_id) is not motion and motion.clip_id not in self._starts:
            given = [k for k, (m, _) in self._starts.items() if own.get(k) is not m]
            if len(given) >= STARTS_EXTRA:
                del self._starts[given[0]]
        self._starts[motion.clip_id] = (motion, good)
        return good

    def _episode_motion(self, motion: Motion) -> FloatArray:
        """``(n_starts,)`` how far the scored keypoints move in each start's episode.

        The mean over the scored keypoints, relative to ``task.motion_anchor``, of
        the largest distance from their position at the start frame.
        """
        span = self.episode_frames * self.frame_skip
        kp = clip_geometry(motion)[:, :N_KEYPOINTS]
        anchor = KEYPOINT_INDEX[self.task.motion_anchor]
        rel = kp[:, self._err_kp] - kp[:, anchor : anchor + 1]  # (T, K, 3)
        steps = np.arange(0, span + 1, self.frame_skip)
        starts = np.arange(motion.n_frames - span)
        moved = rel[starts[:, None] + steps[None]] - rel[starts][:, None]  # (S, F, K, 3)
        return np.linalg.norm(moved, axis=-1).max(axis=1).mean(axis=1)
