"""Motion files and the clips they are: finding them under folders, naming each clip.

:func:`find_clips` lists every BVH and ASF/AMC clip under files and folders
(linked folders followed once each), pairs each AMC with its subject's ASF,
and :func:`describe_file` names a file's clip: its data set, subject, person,
label and clip id (CMU's trial names, Bandai-Namco's file names, else a
user's folder). :mod:`humotion_gym.mocap.library` loads the clips they find.
"""

from __future__ import annotations

import csv
import os
import re
import warnings
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

from humotion_gym.errors import MocapFormatError
from humotion_gym.mocap.cmu import cmu_description, cmu_label, cmu_person, cmu_subject_id
from humotion_gym.mocap.labels import activity_label


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
        clip_id: ``"{dataset}/{file stem}"``; a user's clip ``"user/{folder}/{file
            stem}"``, so that two persons' folders may each hold a ``walk.bvh``.
        person: Who performed it: a CMU person (:func:`~humotion_gym.mocap.cmu.cmu_person`),
            ``"bandai"`` for the Bandai-Namco actors, else the subject id.
    """

    path: Path
    skeleton: Path | None
    dataset: str
    subject: str
    label: str
    description: str
    clip_id: str
    person: str = ""

    @property
    def who(self) -> str:
        """The person id, or the subject id when no person is known."""
        return self.person or self.subject


_BANDAI = re.compile(r"^dataset-(\d)_(?P<content>[a-z\-]+)_(?P<style>[a-z\-]+)_\d+$")
# CMU's names (``02_01``, ``143_07``), also as BVH conversions name them
# (``005_01``, ``cmu_02_01``, ``02_01_poses``).
_CMU = re.compile(r"^(?:cmu[_-]?)?(?P<subject>\d{1,3})_(?P<trial>\d{1,3})(?:[_-][A-Za-z]\w*)?$")


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
    """Dataset, subject, person, label and id of a mocap file, from its name and folder.

    A CMU trial (``SS_TT``, in any format) takes CMU's description from the
    packaged index (:mod:`humotion_gym.mocap.cmu`), else from an ``index.csv``
    beside the files, and its person from the index's person groups.
    """
    stem = path.stem
    m = _BANDAI.match(stem)
    if m:
        dataset = f"bandai-{stem[8]}"
        content, style = m["content"], m["style"]
        return ClipSource(
            path, skeleton, dataset, f"{dataset}/{style}", content,
            f"Bandai-Namco {content}, {style} style", f"{dataset}/{stem}", "bandai",
        )  # fmt: skip
    m = _CMU.match(stem)
    if m:
        subject, trial = int(m["subject"]), int(m["trial"])
        key = f"{subject:02d}_{trial:02d}"
        desc = cmu_description(subject, trial) or _read_cmu_index(path.parent).get(key, "")
        return ClipSource(
            path, skeleton, "cmu", cmu_subject_id(subject), cmu_label(subject, trial, desc),
            desc, f"cmu/{stem}", cmu_person(subject),
        )  # fmt: skip
    label = activity_label(stem)
    # The folder is the person (docs/data.md), and persons' folders often hold
    # files of the same names: the id names both. The folder is read from the
    # absolute path: the same file is the same person (and split) whether it
    # is named "b.bvh" from its folder or by a longer path.
    subject = Path(os.path.abspath(path)).parent.name or "user"
    clip_id = f"user/{subject}/{stem}"
    return ClipSource(path, skeleton, "user", subject, label, "", clip_id, subject)


def _asf_files(folder: Path) -> list[Path]:
    """The ASF files of a folder, by name; the suffix in any case (``02.ASF``), as motion files."""
    return sorted(p for p in folder.iterdir() if p.suffix.lower() == ".asf" and p.is_file())


def _asf_for(amc: Path) -> Path | None:
    """An AMC's skeleton: the ASF of its own name, its subject's ``SS.asf``, else the folder's one.

    ``walk.asf`` beside ``walk.amc`` (one skeleton per clip), then CMU's
    ``02.asf`` beside ``02_01.amc``, then the folder's only ASF unless it is
    named for another subject. Suffixes match in any case (``02_01.AMC`` and
    ``02.ASF``, as written by tools that upper-case names).
    """
    asfs = _asf_files(amc.parent)
    by_stem = {a.stem: a for a in asfs}
    m = _CMU.match(amc.stem)
    for stem in (amc.stem, m["subject"] if m else None):
        if stem is not None and stem in by_stem:
            return by_stem[stem]
    other = asfs[0].stem if len(asfs) == 1 else ""
    if not other or (m and other.isdigit() and int(other) != int(m["subject"])):
        return None  # none, several, or 02.asf beside 03_01.amc
    return asfs[0]


def find_clips(paths: Iterable[str | Path] | str | Path) -> list[ClipSource]:
    """Every BVH and AMC clip under the given files and folders (recursively).

    Partial downloads (``*.part``) are never clips. A file reached twice (a
    folder given relatively and absolutely, a file and its folder, a link) is
    one clip, named by the first path given that reaches it. One trial saved in both
    formats beside each other (CMU's ``16_15.amc`` and its conversion
    ``16_15.bvh``) is one clip: the AMC, CMU's original, is kept and a
    :class:`DuplicateTrialWarning` says how many BVH files were left out.

    Raises:
        FileNotFoundError: If a path does not exist.
        MocapFormatError: If a file given is not ``.bvh`` or ``.amc``, an AMC
            file has no ASF skeleton beside it, or two other files would be
            the same clip (their ids, ``dataset/stem``, are equal).
    """
    files: list[Path] = []
    for p in [paths] if isinstance(paths, (str, Path)) else paths:  # one path, not its letters
        path = Path(p)
        if path.is_dir():
            files.extend(sorted(_motion_files(path)))
        elif path.is_file():
            files.append(path)
        else:
            raise FileNotFoundError(f"{path}: no such file or folder of motion capture")
    unique: dict[str, Path] = {}
    for f in files:
        unique.setdefault(os.path.realpath(f), f)
    out: dict[str, ClipSource] = {}
    converted: list[Path] = []
    for f in sorted(unique.values()):
        suffix = f.suffix.lower()
        if suffix == ".amc":
            asf = _asf_for(f)
            if asf is None:
                cmu = _CMU.match(f.stem)
                wanted = f"{f.stem}.asf" + (f", {cmu['subject']}.asf" if cmu else "")
                beside = ", ".join(a.name for a in _asf_files(f.parent)[:4])
                raise MocapFormatError(
                    f,
                    None,
                    f"no ASF skeleton of its subject beside this AMC file (expected {wanted} "
                    f"or one ASF alone; found {beside or 'none'})",
                )
            src = describe_file(f, asf)
        elif suffix == ".bvh":
            src = describe_file(f)
        else:
            raise MocapFormatError(f, None, "not a motion file (expected .bvh or .amc)")
        seen = out.get(src.clip_id)
        if seen is None:
            out[src.clip_id] = src
        elif seen.path.with_suffix("") == f.with_suffix("") and seen.path.suffix.lower() != suffix:
            amc, bvh = (seen, src) if src.path.suffix.lower() == ".bvh" else (src, seen)
            out[src.clip_id] = amc
            converted.append(bvh.path)
        else:
            raise MocapFormatError(
                f, None, f"the same clip id {src.clip_id} as {seen.path}; rename one or give "
                "only one of their folders",
            )  # fmt: skip
    if converted:
        warnings.warn(
            f"{len(converted)} trial(s) are both .amc and .bvh (e.g. {converted[0]}); "
            "the .amc files, CMU's originals, are used",
            DuplicateTrialWarning,
            stacklevel=2,
        )
    return sorted(out.values(), key=lambda s: s.path)


def _motion_files(folder: Path) -> Iterator[Path]:
    """The ``.bvh`` and ``.amc`` files under ``folder``, linked folders followed once each."""
    seen: set[str] = set()
    for root, dirs, names in os.walk(folder, followlinks=True):
        real = os.path.realpath(root)
        if real in seen:  # a link back up the tree, or a second link to one folder
            dirs.clear()
            continue
        seen.add(real)
        for name in names:
            f = Path(root) / name
            if f.suffix.lower() in (".bvh", ".amc") and f.is_file():
                yield f


class DuplicateTrialWarning(UserWarning):
    """A trial is in a folder twice, as ASF/AMC and as BVH; the AMC is used."""
