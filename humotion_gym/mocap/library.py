"""The motion library: clips with labels, subjects, subject-wise splits and a cache.

A :class:`MotionLibrary` is an immutable collection of :class:`Motion` clips.
:func:`load_library` reads it from folders or files of BVH and ASF/AMC, from
``HUMOTION_MOCAP`` or a ``data_dir`` argument, and caches every parsed and
retargeted clip as ``.npz`` (no pickle) so later loads take seconds; a cached
clip is rebuilt when its source file changes. With no data configured,
:func:`default_library` gives the built-in synthetic motions.

Train and test are split by person (named constants below), checked from the
skeletons: the CMU database by subject number, where the held-out subjects' ASF
skeletons differ from every training skeleton; the Bandai-Namco sets, whose files
do not name their actor and share one skeleton across every style, train whole.
The tracked person is never in a prior's training data.
"""

from __future__ import annotations

import csv
import hashlib
import os
import re
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from humotion_gym.mocap.motion import Motion

#: Version of the cached clip format and retargeting; bump to invalidate caches.
CACHE_VERSION = "1"

#: Environment variable naming folders of real mocap (``os.pathsep``-separated).
MOCAP_ENV = "HUMOTION_MOCAP"
#: Environment variable overriding the cache folder.
CACHE_ENV = "HUMOTION_CACHE"

#: CMU subjects held out for testing, each a different person (their ASF
#: skeletons differ from every training skeleton; checked by
#: :func:`humotion_gym.mocap.persons.check_person_split`). Subject 2 walks, runs,
#: jumps, punches, swings a sword and bends (a bit of everything the tasks
#: track); subject 3 walks on uneven terrain (long walks for the walking tasks).
CMU_TEST_SUBJECTS: tuple[str, ...] = ("cmu-02", "cmu-03")
#: Synthetic subjects held out for testing.
SYNTHETIC_TEST_SUBJECTS: tuple[str, ...] = ("synthetic-05", "synthetic-06")

#: Every held-out person, whatever the data set. The Bandai-Namco sets are not
#: split: their files do not name the actor and every style of both sets shares
#: one skeleton, so no style can be shown to be another person; all of their
#: clips train. A style held out of them is "style held out, same performers".
TEST_SUBJECTS: frozenset[str] = frozenset(CMU_TEST_SUBJECTS + SYNTHETIC_TEST_SUBJECTS)

#: CMU's descriptions of the trials of subjects 1-3 (mocap.cs.cmu.edu); other
#: subjects' descriptions come from an ``index.csv`` beside the files if any.
CMU_DESCRIPTIONS: dict[str, str] = {
    "01_01": "playground - forward jumps, turn around",
    "02_01": "walk",
    "02_02": "walk",
    "02_03": "run/jog",
    "02_04": "jump, balance",
    "02_05": "punch/strike",
    "02_06": "bend over, scoop up, rise, lift arm",
    "02_07": "swordplay",
    "02_08": "swordplay",
    "02_09": "swordplay",
    "02_10": "wash self",
    "03_01": "walk on uneven terrain",
    "03_02": "walk on uneven terrain",
    "03_03": "walk on uneven terrain",
    "03_04": "walk on uneven terrain",
}

# Coarse activity labels from a free-text description: the first rule that
# matches wins, so "walk on uneven terrain" is a walk and "run/jog" a run.
_LABEL_RULES: tuple[tuple[str, str], ...] = (
    (r"\bwalk", "walk"),
    (r"\b(run|jog)", "run"),
    (r"\b(jump|hop)", "jump"),
    (r"\bdance", "dance"),
    (r"\b(punch|strike|box)", "punch"),
    (r"\bsword", "swordplay"),
    (r"\bwash", "wash"),
    (r"\b(bend|scoop|lift|pick)", "lift"),
)


def activity_label(description: str) -> str:
    """A coarse activity label (walk, run, jump, dance...) from a description."""
    text = description.lower()
    for pattern, label in _LABEL_RULES:
        if re.search(pattern, text):
            return label
    return "other"


def default_cache_dir() -> Path:
    """The cache folder: ``$HUMOTION_CACHE``, else ``$XDG_CACHE_HOME/humotion_gym``."""
    if os.environ.get(CACHE_ENV):
        return Path(os.environ[CACHE_ENV])
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "humotion_gym"


@dataclass(frozen=True)
class ClipSource:
    """One clip to load: a BVH file, or an AMC file with its ASF skeleton.

    Attributes:
        path: The motion file (``.bvh`` or ``.amc``).
        skeleton: The ``.asf`` for an AMC file, else None.
        dataset: ``"cmu"``, ``"bandai-1"``, ``"bandai-2"`` or ``"user"``.
        subject: Subject id (``"cmu-02"``, ``"bandai-2/normal"``...).
        label: Coarse activity label.
        description: Free text.
        clip_id: ``"{dataset}/{file stem}"``.
    """

    path: Path
    skeleton: Path | None
    dataset: str
    subject: str
    label: str
    description: str
    clip_id: str


_BANDAI = re.compile(r"^dataset-(\d)_(?P<content>[a-z\-]+)_(?P<style>[a-z\-]+)_\d+$")
_CMU = re.compile(r"^(?P<subject>\d+)_(?P<trial>\d+)$")


def _read_cmu_index(folder: Path) -> dict[str, str]:
    for candidate in (folder / "index.csv", folder.parent / "index.csv"):
        if candidate.is_file():
            out: dict[str, str] = {}
            with open(candidate, newline="", encoding="utf-8", errors="replace") as fh:
                for row in csv.DictReader(fh):
                    try:
                        subject, trial = int(row["Subject"]), int(row["Trial #"])
                    except (KeyError, TypeError, ValueError):
                        continue
                    desc = row.get("Motion Description", "") or ""
                    out[f"{subject:02d}_{trial:02d}"] = desc
            return out
    return {}


def describe_file(path: Path, skeleton: Path | None = None) -> ClipSource:
    """Dataset, subject, label and id of a mocap file, from its name and folder."""
    stem = path.stem
    m = _BANDAI.match(stem)
    if m:
        dataset = f"bandai-{stem[8]}"
        content, style = m["content"], m["style"]
        return ClipSource(
            path, skeleton, dataset, f"{dataset}/{style}", content,
            f"Bandai-Namco {content}, {style} style", f"{dataset}/{stem}",
        )  # fmt: skip
    m = _CMU.match(stem)
    if m:
        subject, trial = int(m["subject"]), int(m["trial"])
        key = f"{subject:02d}_{trial:02d}"
        desc = CMU_DESCRIPTIONS.get(key) or _read_cmu_index(path.parent).get(key, "")
        return ClipSource(
            path, skeleton, "cmu", f"cmu-{subject:02d}",
            activity_label(desc) if desc else "other", desc, f"cmu/{stem}",
        )  # fmt: skip
    label = activity_label(stem)
    return ClipSource(path, skeleton, "user", path.parent.name or "user", label, "", f"user/{stem}")


def _asf_for(amc: Path) -> Path | None:
    m = _CMU.match(amc.stem)
    if m:
        named = amc.parent / f"{m['subject']}.asf"
        if named.is_file():
            return named
    asfs = sorted(amc.parent.glob("*.asf"))
    return asfs[0] if len(asfs) == 1 else None


def find_clips(paths: Iterable[str | Path]) -> list[ClipSource]:
    """Every BVH and AMC clip under the given files and folders (recursively).

    Partial downloads (``*.part``) are never clips.

    Raises:
        FileNotFoundError: If a path does not exist.
        ValueError: If an AMC file has no ASF skeleton beside it.
    """
    files: list[Path] = []
    for p in paths:
        path = Path(p)
        if path.is_dir():
            files.extend(f for f in path.rglob("*") if f.suffix.lower() in (".bvh", ".amc"))
        elif path.is_file():
            files.append(path)
        else:
            raise FileNotFoundError(f"{path}: no such file or folder of motion capture")
    out = []
    for f in sorted(set(files)):
        suffix = f.suffix.lower()
        if suffix == ".amc":
            asf = _asf_for(f)
            if asf is None:
                raise ValueError(f"{f}: no ASF skeleton found beside this AMC file")
            out.append(describe_file(f, asf))
        elif suffix == ".bvh":
            out.append(describe_file(f))
        else:
            raise ValueError(f"{f}: not a motion file (expected .bvh or .amc)")
    return out


def _cache_key(src: ClipSource, fps: float | None) -> str:
    parts = [CACHE_VERSION, str(fps)]
    for f in (src.path, src.skeleton):
        if f is not None:
            st = f.stat()
            parts += [str(f.resolve()), str(st.st_size), str(st.st_mtime_ns)]
    return hashlib.sha256("|".join(parts).encode()).hexdigest()[:32]


def load_clip(src: ClipSource, fps: float | None = 30.0) -> Motion:
    """Parse and retarget one clip (no cache).

    Raises:
        MocapFormatError: If the file is malformed.
        RigError: If its skeleton cannot be mapped onto the cone body.
    """
    from humotion_gym.mocap.asfamc import load_amc, load_asf
    from humotion_gym.mocap.bvh import load_bvh
    from humotion_gym.mocap.retarget import retarget_clip

    if src.skeleton is not None:
        clip = load_amc(src.path, load_asf(src.skeleton))
    else:
        clip = load_bvh(src.path)
    result = retarget_clip(clip, fps=fps)
    return Motion(
        clip_id=src.clip_id,
        params=result.params,
        velocities=result.velocities,
        observed=result.observed,
        fps=result.fps,
        shape=result.shape,
        keypoints=result.keypoints,
        subject=src.subject,
        label=src.label,
        source=str(src.path),
        dataset=src.dataset,
        description=src.description,
        meta={"rig": result.rig.name, "units_to_mm": f"{result.units_to_mm:g}"},
    )


@dataclass(frozen=True)
class MotionLibrary:
    """An immutable collection of clips.

    Attributes:
        motions: The clips, in load order.
        test_subjects: The subjects of the ``"test"`` split; None for the
            project's held-out persons (:data:`TEST_SUBJECTS`). A validation
            fold (:meth:`validation_fold`) names its own.
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
        """A text table: one row per clip, then totals."""
        head = f"{'clip':32s} {'subject':22s} {'label':10s} {'frames':>7s} {'fps':>5s} {'sec':>7s}"
        lines = [head, "-" * len(head)]
        for m in self.motions:
            lines.append(
                f"{m.clip_id:32s} {m.subject:22s} {m.label:10s} {m.n_frames:7d} "
                f"{m.fps:5.0f} {m.duration:7.1f}"
            )
        seconds = sum(m.duration for m in self.motions)
        kind = " (synthetic)" if self.is_synthetic else ""
        lines.append(
            f"{len(self)} clips{kind}, {self.total_frames} frames, {seconds:.0f} s, "
            f"{len(self.subjects)} subjects; test split: {len(self.split('test'))} clips"
        )
        return "\n".join(lines)


def load_library(
    paths: Iterable[str | Path],
    fps: float | None = 30.0,
    cache_dir: str | Path | None = None,
    use_cache: bool = True,
    progress: bool = True,
) -> MotionLibrary:
    """Load every clip under the given files and folders.

    The first load parses and retargets each clip (with a progress bar) and
    writes it to ``cache_dir/clips`` as ``.npz``; later loads read the cache.
    A clip is rebuilt when its file's size or modification time changes.

    Args:
        paths: Files or folders of BVH and ASF/AMC.
        fps: The library's frame rate (None keeps each file's).
        cache_dir: Where to cache (``default_cache_dir()`` when None).
        use_cache: Read and write the cache.
        progress: Show a progress bar while parsing.

    Returns:
        The library, clips sorted by path.
    """
    sources = find_clips(paths)
    cache = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    clip_dir = cache / "clips"
    motions: list[Motion] = []
    todo: list[tuple[ClipSource, Path]] = []
    for src in sources:
        target = clip_dir / f"{_cache_key(src, fps)}.npz"
        if use_cache and target.is_file():
            try:
                motions.append(Motion.load(target))
                continue
            except ValueError:
                pass  # a damaged cache entry is rebuilt below
        todo.append((src, target))
    if todo:
        if use_cache:
            clip_dir.mkdir(parents=True, exist_ok=True)
        bar = tqdm(todo, desc="parsing mocap", unit="clip", disable=not progress or len(todo) < 2)
        for src, target in bar:
            motion = load_clip(src, fps)
            if use_cache:
                tmp = target.with_suffix(f".{os.getpid()}.tmp")
                motion.save(tmp)
                os.replace(tmp, target)
            motions.append(motion)
    order = {src.clip_id: i for i, src in enumerate(sources)}
    motions.sort(key=lambda m: order.get(m.clip_id, 0))
    return MotionLibrary(tuple(motions))


def configured_data_dirs(data_dir: str | Path | Sequence[str | Path] | None = None) -> list[Path]:
    """The folders of real mocap: ``data_dir`` if given, else ``$HUMOTION_MOCAP``."""
    if data_dir is not None:
        items = [data_dir] if isinstance(data_dir, (str, Path)) else list(data_dir)
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
