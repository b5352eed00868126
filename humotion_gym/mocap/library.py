"""The motion library: clips with labels, subjects, subject-wise splits and a cache.

A :class:`MotionLibrary` is an immutable collection of :class:`Motion` clips.
:func:`load_library` reads it from folders or files of BVH and ASF/AMC, from
``HUMOTION_MOCAP`` or a ``data_dir`` argument, and caches every parsed and
retargeted clip as ``.npz`` (no pickle) so later loads take seconds; a cached
clip is rebuilt when its source file changes, and a damaged or foreign entry is
reported (:class:`CacheWarning`) and rebuilt. With no data configured,
:func:`default_library` gives the built-in synthetic motions.

Train and test are split by person: :mod:`humotion_gym.mocap.splits` names
who each data set holds out and why, :mod:`humotion_gym.mocap.persons` checks
it from the skeletons, and a user's folders follow :func:`user_split` unless
``load_library(split_by=...)`` says otherwise. Every clip's person, split and
the rule that put it there are in its ``meta``, and loading refuses a person
on both sides. The tracked person is never in a prior's training data.
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import warnings
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from humotion_gym.checks import is_real
from humotion_gym.files import write_atomically
from humotion_gym.mocap._cache_files import (  # CacheWarning: re-exported, part of the API
    CACHE_ERRORS,
    CacheWarning,  # noqa: F401
    entry_places,
    package_version,
    placed_entry_path,
    remove_stale_entries,
    report_cache_problem,
    report_unwritten,
)
from humotion_gym.mocap.clip_files import (  # re-exported, part of the API
    ClipSource,
    DuplicateTrialWarning,  # noqa: F401
    describe_file,  # noqa: F401
    find_clips,
)
from humotion_gym.mocap.labels import activity_label  # noqa: F401  (re-exported)
from humotion_gym.mocap.motion import Motion
from humotion_gym.mocap.splits import (  # the split's names, re-exported
    CMU_TEST_SUBJECTS,  # noqa: F401
    CMU_VALIDATION_SUBJECTS,  # noqa: F401
    EPISODE_SPLITS,
    SPLIT_RULES,
    SYNTHETIC_TEST_SUBJECTS,  # noqa: F401
    SYNTHETIC_VALIDATION_SUBJECTS,  # noqa: F401
    TEST_SUBJECTS,
    USER_SPLIT_RULE,
    VALIDATION_SUBJECTS,
    user_split,
)

#: Version of the cached clip format and retargeting; bump to invalidate caches
#: whenever parsing or retargeting changes what a clip holds.
CACHE_VERSION = "5"

#: Environment variable naming folders of real mocap (``os.pathsep``-separated).
MOCAP_ENV = "HUMOTION_MOCAP"
#: Environment variable overriding the cache folder.
CACHE_ENV = "HUMOTION_CACHE"

#: What ``load_library(split_by=...)`` accepts for a user's clips: a function of
#: a clip's :class:`ClipSource` returning ``"train"`` or ``"test"``, or a mapping
#: from clip ids, subject ids or person ids to ``"train"``/``"test"``.
SplitBy = Callable[["ClipSource"], str] | Mapping[str, str]


def default_cache_dir() -> Path:
    """The cache folder: ``$HUMOTION_CACHE``, else ``$XDG_CACHE_HOME/humotion_gym``.

    A leading ``~`` is expanded, as a shell would: a quoted ``'~/cache'`` reaches
    the process unexpanded and would otherwise make a folder named ``~`` here.
    """
    if os.environ.get(CACHE_ENV):
        return Path(os.environ[CACHE_ENV]).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base).expanduser() / "humotion_gym"


def assign_split(src: ClipSource, split_by: SplitBy | None = None) -> tuple[str, str]:
    """A clip's split and the rule that decided it.

    Known data sets follow the benchmark's split (:data:`TEST_SUBJECTS`,
    :data:`SPLIT_RULES`). A user's clip follows ``split_by`` when given (a
    function of the :class:`ClipSource`, or a mapping looked up by clip id,
    then subject id, then person id; a clip the mapping does not name falls
    back on the default), else :func:`user_split` of its person.

    Returns:
        ``("train" | "test", rule)``.

    Raises:
        ValueError: If ``split_by`` gives something other than ``"train"``/``"test"``.
    """
    if src.dataset != "user":
        split = "test" if src.subject in TEST_SUBJECTS else "train"
        return split, SPLIT_RULES.get(src.dataset, src.dataset)
    if split_by is not None:
        if callable(split_by):
            value, rule = split_by(src), f"split_by={getattr(split_by, '__name__', 'function')}"
        else:
            key = next((k for k in (src.clip_id, src.subject, src.who) if k in split_by), None)
            value, rule = (split_by[key], f"split_by mapping ({key})") if key else (None, "")
        if value is not None:
            if value not in ("train", "test"):
                raise ValueError(
                    f"split_by: expected 'train' or 'test' for {src.clip_id}, got {value!r}"
                )
            return value, rule
    return user_split(src.who), USER_SPLIT_RULE


def _warn_unused_split_keys(split_by: Mapping[str, str], sources: Sequence[ClipSource]) -> None:
    """Warn of each key of a ``split_by`` mapping that decides no clip's split.

    A key of a known data set's clip, subject or person is ignored (their
    split is the benchmark's), as is one that names nothing loaded: either
    way the user's intent is dropped, so it is said.
    """
    user = {k for s in sources if s.dataset == "user" for k in (s.clip_id, s.subject, s.who)}
    known = {k: s for s in sources if s.dataset != "user" for k in (s.clip_id, s.subject, s.who)}
    for key in split_by:
        if key in user:
            continue
        why = (
            f"is {known[key].dataset} data, which keeps the benchmark's split"
            if key in known
            else "names no clip, subject or person loaded"
        )
        warnings.warn(f"split_by: {key!r} {why}; ignored", UserWarning, stacklevel=3)


class SplitError(ValueError):
    """A person is on both sides of the split, or shares a skeleton across it.

    Raised by :func:`check_person_sides` (a person's clips on both sides) and
    :func:`humotion_gym.mocap.persons.check_person_split` (a held-out person's
    skeleton also in the training data).

    Attributes:
        pairs: Every ``(test, train)`` pair of subjects, persons or clips at fault.
    """

    def __init__(self, message: str, pairs: Sequence[tuple[str, str]]) -> None:
        super().__init__(message)
        self.pairs: tuple[tuple[str, str], ...] = tuple(pairs)


def check_person_sides(assigned: Sequence[tuple[ClipSource, str]]) -> None:
    """Refuse a person with clips in both splits.

    Raises:
        SplitError: Naming each such person and one clip on each side.
    """
    sides: dict[str, dict[str, str]] = {}
    for src, split in assigned:
        sides.setdefault(src.who, {}).setdefault(split, src.clip_id)
    both = {p: v for p, v in sides.items() if len(v) > 1}
    if both:
        lines = [f"  {p}: train {v['train']}, test {v['test']}" for p, v in sorted(both.items())]
        raise SplitError(
            f"{len(both)} person(s) on both sides of the split (split_by must put all of a "
            "person's clips on one side):\n" + "\n".join(lines),
            [(v["test"], v["train"]) for v in both.values()],
        )


def _cache_key(src: ClipSource, fps: float | None) -> str:
    """The clip cache key: versions, frame rate, the clip's id and person, the files' stats.

    The id and person are in it because a linked file shares its target's
    stats but is another clip (its own name and folder).
    """
    parts = [CACHE_VERSION, package_version(), str(fps), src.clip_id, src.subject]
    for f in (src.path, src.skeleton):
        if f is not None:
            st = f.stat()
            parts += [str(f.resolve()), str(st.st_size), str(st.st_mtime_ns)]
    return hashlib.sha256("|".join(parts).encode()).hexdigest()[:32]


def clips_fingerprint(paths: Sequence[str | Path], fps: float | None) -> str:
    """What :func:`load_library` of ``paths`` at ``fps`` would give, as the clip cache sees it.

    The digest of every clip's cache key (:func:`_cache_key`: its id, person,
    resolved files' paths, sizes and modification times, the frame rate and
    versions), so it changes exactly when a cache entry would: a clip added,
    removed or renamed, a file rewritten. It lists and stats the files but
    parses none; a :class:`DuplicateTrialWarning` is left for the load itself
    to give.

    Raises:
        FileNotFoundError: If a path does not exist (as :func:`load_library`).
        MocapFormatError: If the files are not clips (as :func:`load_library`).
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DuplicateTrialWarning)
        sources = find_clips(paths)
    keys = "|".join(_cache_key(src, fps) for src in sources)
    return hashlib.sha256(keys.encode()).hexdigest()


def _cache_place(src: ClipSource, fps: float | None) -> str:
    """The clip at a frame rate (its id, person and files' paths), not its stats or versions.

    The stale entries of a clip whose file changed, or of an earlier version,
    share it with the new one, which removes them when it is written
    (:func:`~humotion_gym.mocap._cache_files.remove_stale_entries`).
    """
    parts = [str(fps), src.clip_id, src.subject]
    parts += [str(f.resolve()) for f in (src.path, src.skeleton) if f is not None]
    return hashlib.sha256("|".join(parts).encode()).hexdigest()[:12]


def _clip_entry(
    clip_dir: Path, src: ClipSource, fps: float | None
) -> tuple[str, dict[str, str], str, Path | None, str | None]:
    """A clip's cache key, stored info (checked on read), place, file, what blocked it."""
    key, place = _cache_key(src, fps), _cache_place(src, fps)
    target, blocked = placed_entry_path(clip_dir, place, key, legacy=key)
    info = {
        "key": key,
        "clip_id": src.clip_id,
        "source": str(src.path.resolve()),
        "skeleton": str(src.skeleton.resolve()) if src.skeleton is not None else "",
        "fps": str(fps),
        "cache_version": CACHE_VERSION,
        "package_version": package_version(),
    }
    return key, info, place, target, blocked


def _read_clip_entry(path: Path, src: ClipSource, info: Mapping[str, str]) -> Motion:
    """The cached clip at ``path``, checked against what was asked for.

    The stored key, clip id, source, frame rate and versions must all equal
    ``info``; the clip's metadata (subject, label...) is refreshed from ``src``.

    Raises:
        ValueError: If the entry is unreadable, damaged or another clip's.
    """
    motion, stored = Motion.load_with_extra(path)
    wrong = [k for k in info if stored.get(k) != info[k]]
    if motion.clip_id != src.clip_id and "clip_id" not in wrong:
        wrong.append("clip_id")
    if wrong:
        shown = ", ".join(f"{k}={stored.get(k, '(none)')!r} (expected {info[k]!r})" for k in wrong)
        raise ValueError(f"a foreign entry: {shown}")
    fresh = {
        "source": str(src.path),
        "subject": src.subject,
        "label": src.label,
        "dataset": src.dataset,
        "description": src.description,
    }
    if any(getattr(motion, k) != v for k, v in fresh.items()):
        motion = dataclasses.replace(motion, **fresh)
    return motion


def _with_split(motion: Motion, src: ClipSource, split: tuple[str, str]) -> Motion:
    """The motion with its person and split (which may change without the file) in ``meta``."""
    want = {"person": src.who, "split": split[0], "split_rule": split[1]}
    if all(motion.meta.get(k) == v for k, v in want.items()):
        return motion
    return dataclasses.replace(motion, meta={**motion.meta, **want})


def load_clip(
    src: ClipSource, fps: float | None = 30.0, split: tuple[str, str] | None = None
) -> Motion:
    """Parse and retarget one clip (no cache).

    The rig is matched by :func:`humotion_gym.mocap.rigmap.match_rig` (a
    built-in profile, else names and topology); a T-pose at frame 0 is dropped
    (:func:`humotion_gym.mocap.tpose.is_tpose_frame`). ``meta`` records the
    rig, how it was matched and how sure, the T-pose, the person and the split.

    Args:
        src: The clip.
        fps: The frame rate (None keeps the file's).
        split: ``(split, rule)``; :func:`assign_split` with no ``split_by`` when None.

    Raises:
        MocapFormatError: If the file is malformed.
        RigError: If its skeleton cannot be mapped onto the cone body.
        TypeError: If ``src`` is not a :class:`ClipSource` (a path is not: it
            says nothing of the clip's person or dataset;
            :func:`~humotion_gym.mocap.clip_files.find_clips` makes them).
    """
    if not isinstance(src, ClipSource):
        raise TypeError(
            f"load_clip: src: expected a ClipSource (humotion_gym.mocap.clip_files.find_clips"
            f"(path) gives a file's), got {type(src).__name__} {src!r:.200}"
        )
    from humotion_gym.mocap.asfamc import load_amc, load_asf
    from humotion_gym.mocap.bvh import load_bvh
    from humotion_gym.mocap.retarget import file_units_to_mm, retarget_keypoints, velocities
    from humotion_gym.mocap.rigmap import match_rig
    from humotion_gym.mocap.tpose import is_tpose_frame

    if src.skeleton is not None:
        clip = load_amc(src.path, load_asf(src.skeleton))
    else:
        clip = load_bvh(src.path)
    match = match_rig(clip)
    units = file_units_to_mm(clip, match.profile)
    keypoints = match.profile.keypoints_from(clip, units)
    valid = np.asarray(clip.frame_valid, dtype=bool)
    tpose = bool(valid[:2].all()) and is_tpose_frame(keypoints[:2])
    if tpose:
        keypoints, valid = keypoints[1:], valid[1:]
    # (file_units_to_mm refused a clip without a whole frame; a T-pose is
    # only found before another whole frame, so one is left)
    source = f"{src.path} (rig {match.profile.name}, matched by {match.method})"
    params, observed, kp, shape = retarget_keypoints(keypoints, clip.fps, fps, valid, source=source)
    out_fps = clip.fps if fps is None else fps
    split, rule = split if split is not None else assign_split(src)
    return Motion(
        clip_id=src.clip_id,
        params=params,
        velocities=velocities(params, out_fps),
        observed=observed,
        fps=out_fps,
        shape=shape,
        keypoints=kp,
        subject=src.subject,
        label=src.label,
        source=str(src.path),
        dataset=src.dataset,
        description=src.description,
        meta={
            "rig": match.profile.name,
            "rig_match": match.method,
            "rig_confidence": f"{match.confidence:.2f}",
            "rig_summary": match.summary(),
            "units_to_mm": f"{units:g}",
            "tpose": "dropped frame 0" if tpose else "",
            "person": src.who,
            "split": split,
            "split_rule": rule,
        },
    )


@dataclass(frozen=True)
class MotionLibrary:
    """An immutable collection of clips.

    Attributes:
        motions: The clips, in load order.
        test_subjects: The subjects of the ``"test"`` split; None for the
            project's held-out persons (:data:`TEST_SUBJECTS`). A validation
            fold (:meth:`validation_fold`) names its own; :func:`load_library`
            adds a user's test persons to :data:`TEST_SUBJECTS`.
    """

    motions: tuple[Motion, ...]
    test_subjects: frozenset[str] | None = None

    def __post_init__(self) -> None:
        ids = [m.clip_id for m in self.motions]
        if len(set(ids)) != len(ids):
            dup = sorted({i for i in ids if ids.count(i) > 1})
            raise ValueError(f"MotionLibrary: clip ids must be unique, repeated: {dup[:5]}")

    def __len__(self) -> int:
        return len(self.motions)

    def __iter__(self) -> Iterator[Motion]:
        return iter(self.motions)

    def __getitem__(self, key: int | str) -> Motion:
        if isinstance(key, str):
            for m in self.motions:
                if m.clip_id == key:
                    return m
            raise KeyError(f"no clip {key!r} in the library (e.g. {self.clip_ids[:3]})")
        return self.motions[key]

    @property
    def clip_ids(self) -> list[str]:
        """The clips' ids."""
        return [m.clip_id for m in self.motions]

    @property
    def total_frames(self) -> int:
        """Frames over all clips."""
        return int(sum(m.n_frames for m in self.motions))

    @property
    def subjects(self) -> list[str]:
        """Distinct subjects, sorted."""
        return sorted({m.subject for m in self.motions})

    @property
    def labels(self) -> list[str]:
        """Distinct labels, sorted."""
        return sorted({m.label for m in self.motions})

    @property
    def split_rules(self) -> list[str]:
        """The rules that split the clips (from each clip's ``meta``), sorted."""
        rules = {m.meta.get("split_rule") or SPLIT_RULES.get(m.dataset, "") for m in self.motions}
        return sorted(r for r in rules if r)

    @property
    def is_synthetic(self) -> bool:
        """True when every clip is built-in synthetic motion."""
        return bool(self.motions) and all(m.synthetic for m in self.motions)

    def filter(
        self,
        labels: Sequence[str] | None = None,
        subjects: Sequence[str] | None = None,
        datasets: Sequence[str] | None = None,
        min_frames: int = 1,
    ) -> MotionLibrary:
        """The clips matching every given criterion."""
        keep = [
            m
            for m in self.motions
            if (labels is None or m.label in labels)
            and (subjects is None or m.subject in subjects)
            and (datasets is None or m.dataset in datasets)
            and m.n_frames >= min_frames
        ]
        return MotionLibrary(tuple(keep), self.test_subjects)

    @property
    def held_out(self) -> frozenset[str]:
        """The subjects of the ``"test"`` split."""
        return TEST_SUBJECTS if self.test_subjects is None else self.test_subjects

    def split(self, which: str) -> MotionLibrary:
        """The ``"train"`` or ``"test"`` clips, by person (see :attr:`held_out`)."""
        if which not in ("train", "test"):
            raise ValueError(f"split: expected 'train' or 'test', got {which!r}")
        test = which == "test"
        held = self.held_out
        return MotionLibrary(
            tuple(m for m in self.motions if (m.subject in held) == test), self.test_subjects
        )

    def episode_split(self, which: str) -> MotionLibrary:
        """The clips an environment of split ``which`` draws its episodes from.

        ``"train"``: the training persons less the validation persons
        (:data:`VALIDATION_SUBJECTS`); ``"validation"``: the validation persons
        (settings are chosen on them); ``"test"``: the held-out persons
        (:attr:`held_out`), for the leaderboard.

        Raises:
            ValueError: For another split, or ``"validation"`` on a library
                without a validation person.
        """
        if which not in EPISODE_SPLITS:
            raise ValueError(f"split: expected one of {list(EPISODE_SPLITS)}, got {which!r}")
        if which == "test":
            return self.split("test")
        train = self.split("train")
        validation = which == "validation"
        chosen = MotionLibrary(
            tuple(m for m in train if (m.subject in VALIDATION_SUBJECTS) == validation),
            self.test_subjects,
        )
        if validation and len(chosen) == 0:
            raise ValueError(
                "split='validation': the library holds none of the validation persons "
                f"{sorted(VALIDATION_SUBJECTS)} (its training persons: {train.subjects})"
            )
        return chosen

    def unseen_by(self, which: str) -> frozenset[str]:
        """The persons an environment of split ``which`` must never show.

        ``"train"``: the test and validation persons; ``"validation"``: the
        test persons; ``"test"``: none.
        """
        if which == "train":
            return self.held_out | VALIDATION_SUBJECTS
        if which == "validation":
            return self.held_out
        return frozenset()

    def validation_fold(self, subjects: Sequence[str]) -> MotionLibrary:
        """The training split with ``subjects`` held out as its own test split.

        Settings are chosen on such folds (cross-validation within the training
        persons), never on the test persons: priors fit on the rest of the
        training split and environments made with ``library=`` this fold track
        the held-out training subjects.

        Raises:
            ValueError: If a subject is a test person or absent from the
                training split.
        """
        train = self.split("train")
        chosen = frozenset(subjects)
        wrong = sorted(chosen & self.held_out)
        if wrong:
            raise ValueError(f"validation_fold: {wrong} are test persons, never used to choose")
        missing = sorted(chosen - set(train.subjects))
        if missing or not chosen:
            raise ValueError(
                f"validation_fold: subjects {missing or '(none)'} are not in the training split "
                f"(its subjects: {train.subjects})"
            )
        return MotionLibrary(train.motions, test_subjects=chosen)

    def table(self) -> str:
        """A text table: one row per clip (person and split included), totals, split rules."""
        head = (
            f"{'clip':32s} {'subject':22s} {'person':16s} {'split':5s} {'label':10s} "
            f"{'frames':>7s} {'fps':>5s} {'sec':>7s}"
        )
        lines = [head, "-" * len(head)]
        held = self.held_out
        for m in self.motions:
            split = "test" if m.subject in held else "train"
            lines.append(
                f"{m.clip_id:32s} {m.subject:22s} {m.meta.get('person', m.subject):16s} "
                f"{split:5s} {m.label:10s} {m.n_frames:7d} {m.fps:5.0f} {m.duration:7.1f}"
            )
        seconds = sum(m.duration for m in self.motions)
        kind = " (synthetic)" if self.is_synthetic else ""
        lines.append(
            f"{len(self)} clips{kind}, {self.total_frames} frames, {seconds:.0f} s, "
            f"{len(self.subjects)} subjects; test split: {len(self.split('test'))} clips"
        )
        lines += [f"split rule: {r}" for r in self.split_rules]
        return "\n".join(lines)


def _frame_rate(fps: object) -> float | None:
    """``fps`` as a float (30 and 30.0: one cache entry, not two), or None.

    Raises:
        ValueError: If it is neither None nor a positive frame rate.
    """
    if fps is not None and not (is_real(fps) and np.isfinite(fps) and fps > 0):
        raise ValueError(f"load_library: fps must be None or a positive frame rate, got {fps!r}")
    return None if fps is None else float(fps)  # type: ignore[arg-type]


def load_library(
    paths: Iterable[str | Path] | str | Path,
    fps: float | None = 30.0,
    cache_dir: str | Path | None = None,
    use_cache: bool = True,
    progress: bool = True,
    split_by: SplitBy | None = None,
) -> MotionLibrary:
    """Load every clip under the given files and folders.

    The first load parses and retargets each clip (with a progress bar) and
    writes it to ``cache_dir/clips`` as ``.npz``; later loads read the cache.
    A clip is rebuilt when its file's size or modification time, the frame
    rate, :data:`CACHE_VERSION` or the package version changes (all part of
    the key). The cache heals: an entry that is unreadable (truncated, empty,
    corrupted, a ``.npy``, a directory), holds data of the wrong types or
    another clip's or version's data (each entry stores its key, clip id and
    source, compared on read) is reported once with a :class:`CacheWarning`
    naming the file, rebuilt and overwritten. Entries are written atomically.

    Args:
        paths: Files or folders of BVH and ASF/AMC (or one of them).
        fps: The library's frame rate (None keeps each file's).
        cache_dir: Where to cache (``default_cache_dir()`` when None).
        use_cache: Read and write the cache.
        progress: Show a progress bar while parsing.
        split_by: How to split a user's clips (those of no known data set):
            a function of a :class:`ClipSource` returning ``"train"`` or
            ``"test"``, or a mapping from clip, subject or person ids to
            them; :func:`user_split` (one person in five to test, by hash)
            for clips it leaves out. CMU, Bandai-Namco and synthetic clips
            keep the benchmark's split: a mapping's key of theirs, or one
            that names nothing loaded, is warned of and ignored. Each clip's
            ``meta["split_rule"]`` and :attr:`MotionLibrary.split_rules` say
            which rule was used.

    Returns:
        The library, clips sorted by path; its test split is
        :data:`TEST_SUBJECTS` plus the user's test persons.

    Raises:
        SplitError: If ``split_by`` puts one person on both sides.
        TypeError: If ``paths`` is not a path or an iterable of them.
        ValueError: If ``fps`` is neither None nor a positive frame rate.
    """
    if not isinstance(paths, (str, Path)):
        if not isinstance(paths, Iterable):
            raise TypeError(f"load_library: paths must be a path or paths, got {paths!r}")
        paths = list(paths)  # (an iterator is read once, here)
        if not all(isinstance(p, (str, Path)) for p in paths):
            raise TypeError(f"load_library: paths must be a path or paths, got {paths!r}")
    fps = _frame_rate(fps)
    sources = find_clips(paths)
    if split_by is not None and not callable(split_by):
        _warn_unused_split_keys(split_by, sources)
    assigned = [(src, assign_split(src, split_by)) for src in sources]
    check_person_sides([(src, split[0]) for src, split in assigned])
    splits = {src.clip_id: split for src, split in assigned}
    user_test = frozenset(
        src.subject for src, (split, _) in assigned if src.dataset == "user" and split == "test"
    )
    cache = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    clip_dir = cache / "clips"
    motions: list[Motion] = []
    todo: list[tuple[ClipSource, Path | None, dict[str, str], str, str]] = []
    for src in sources:
        if not use_cache:
            todo.append((src, None, {}, "", ""))
            continue
        key, info, place, target, blocked = _clip_entry(clip_dir, src, fps)
        problem = blocked
        if target is not None and (target.exists() or target.is_symlink()):
            try:
                motions.append(
                    _with_split(_read_clip_entry(target, src, info), src, splits[src.clip_id])
                )
                continue
            except CACHE_ERRORS as exc:
                why = str(exc).removeprefix(f"{target}: ")
                problem = (f"{blocked}; " if blocked else "") + f"bad entry of {src.clip_id}: {why}"
        if problem is not None:
            report_cache_problem(
                target or clip_dir / f"{place}-{key}.npz", f"{problem}; rebuilding it"
            )
        todo.append((src, target, info, place, key))
    held = entry_places(clip_dir) if use_cache and todo else set()
    bar = tqdm(todo, desc="parsing mocap", unit="clip", disable=not progress or len(todo) < 2)
    for src, target, info, place, key in bar:
        motion = load_clip(src, fps, splits[src.clip_id])
        if target is not None:
            try:
                write_atomically(target, lambda tmp, m=motion, i=info: m.save(tmp, extra=i))
                if place in held or key in held:
                    remove_stale_entries(clip_dir, place, target, legacy=key)
            except CACHE_ERRORS as exc:
                report_unwritten(target, exc)
        motions.append(motion)
    order = {src.clip_id: i for i, src in enumerate(sources)}
    motions.sort(key=lambda m: order.get(m.clip_id, 0))
    return MotionLibrary(tuple(motions), TEST_SUBJECTS | user_test if user_test else None)


def configured_data_dirs(data_dir: str | Path | Sequence[str | Path] | None = None) -> list[Path]:
    """The folders of real mocap: ``data_dir`` if given, else ``$HUMOTION_MOCAP``.

    An empty list is none, whatever ``$HUMOTION_MOCAP`` says: the built-in
    synthetic motion.
    """
    if data_dir is not None:
        items = [data_dir] if isinstance(data_dir, (str, Path)) else data_dir
        if not isinstance(items, (list, tuple)) or not all(
            isinstance(p, (str, Path)) and str(p) != "" for p in items
        ):
            raise ValueError(
                f"data_dir: expected a folder (str or Path) or a list of them, got {data_dir!r}"
            )
        return [Path(p) for p in items]
    env = os.environ.get(MOCAP_ENV, "")
    return [Path(p) for p in env.split(os.pathsep) if p]


def synthetic_library(seed: int = 0, fps: float = 30.0) -> MotionLibrary:
    """The built-in synthetic motion set (no files needed)."""
    from humotion_gym.mocap.synthetic import synthetic_motions

    return MotionLibrary(tuple(synthetic_motions(seed=seed, fps=fps)))


def default_library(
    data_dir: str | Path | Sequence[str | Path] | None = None,
    fps: float = 30.0,
    progress: bool = True,
) -> MotionLibrary:
    """Real mocap from ``data_dir`` or ``$HUMOTION_MOCAP``, else the synthetic set."""
    dirs = configured_data_dirs(data_dir)
    if not dirs:
        return synthetic_library(fps=fps)
    return load_library(dirs, fps=fps, progress=progress)


def library_summary(library: MotionLibrary) -> dict[str, dict[str, float]]:
    """Per data set: clips, frames, seconds and the retargeting error in mm.

    The error (:meth:`Motion.retarget_error`, per observed frame) is summarised
    by its mean, median, 95th percentile and maximum.
    """
    out: dict[str, dict[str, float]] = {}
    for name in sorted({m.dataset for m in library}):
        clips = [m for m in library if m.dataset == name]
        errors = np.concatenate([m.retarget_error() for m in clips])
        errors = errors[np.isfinite(errors)]
        stats = {"mean": np.mean, "median": np.median, "p95": lambda e: np.percentile(e, 95),
                 "max": np.max}  # fmt: skip
        out[name] = {
            "clips": len(clips),
            "frames": int(sum(m.n_frames for m in clips)),
            "seconds": float(sum(m.duration for m in clips)),
            **{
                f"error_{k}_mm": float(f(errors)) if errors.size else float("nan")
                for k, f in stats.items()
            },
        }
    return out
