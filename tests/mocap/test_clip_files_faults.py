"""Finding clip files and naming their clips: contracts of find_clips and describe_file."""

from __future__ import annotations

import warnings
from pathlib import Path

import pytest

from humotion_gym.errors import MocapFormatError
from humotion_gym.mocap.clip_files import DuplicateTrialWarning, describe_file, find_clips

INDEX_CSV = "Subject,Trial #,Motion Description\n13,99,walk slowly\n13,98,jump high\n"


def touch(path: Path, text: str = "") -> Path:
    """Create ``path`` (and its folders) holding ``text``; find_clips never reads it."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


@pytest.mark.parametrize("where", ["folder", "parent"])
def test_an_index_csv_beside_or_above_describes_unlisted_trials(tmp_path: Path, where: str) -> None:
    """13_99 is not in the packaged listing: its index.csv row names and labels it."""
    clip = touch(tmp_path / "cmu" / "13" / "13_99.bvh")
    touch((clip.parent if where == "folder" else clip.parent.parent) / "index.csv", INDEX_CSV)
    src = describe_file(clip)
    assert (src.description, src.label, src.subject) == ("walk slowly", "walk", "cmu-13")


def test_a_converted_cmu_name_keeps_its_stem_as_clip_id(tmp_path: Path) -> None:
    """clip_id is "{dataset}/{file stem}", the stem as written (cmu_16_11, 143_25_poses)."""
    for stem in ("cmu_16_11", "143_25_poses", "005_01"):
        assert describe_file(tmp_path / f"{stem}.bvh").clip_id == f"cmu/{stem}"


def test_an_amc_among_several_asfs_of_no_subject_is_refused(tmp_path: Path) -> None:
    """walk.amc beside a.asf and b.asf: which skeleton is unknown, so none is guessed."""
    for name in ("a.asf", "b.asf", "walk.amc"):
        touch(tmp_path / name)
    with pytest.raises(MocapFormatError, match=r"walk\.amc: no ASF skeleton.*found a\.asf, b\.asf"):
        find_clips([tmp_path])
    (tmp_path / "b.asf").unlink()
    assert [s.skeleton for s in find_clips([tmp_path])] == [tmp_path / "a.asf"]


def test_a_trial_in_both_formats_keeps_the_amc(tmp_path: Path) -> None:
    """16_15.amc and its conversion 16_15.bvh side by side: one clip, the AMC, and a warning."""
    for name in ("16.asf", "16_15.amc", "16_15.bvh"):
        touch(tmp_path / name)
    with pytest.warns(DuplicateTrialWarning, match=r"1 trial\(s\).*16_15\.bvh"):
        found = find_clips([tmp_path])
    assert [(s.path.name, s.skeleton) for s in found] == [("16_15.amc", tmp_path / "16.asf")]


def test_one_trial_in_two_folders_is_refused(tmp_path: Path) -> None:
    """a/16_15.amc and b/16_15.bvh are two files of one clip id, not one trial twice."""
    touch(tmp_path / "a" / "16.asf")
    touch(tmp_path / "a" / "16_15.amc")
    touch(tmp_path / "b" / "16_15.bvh")
    with warnings.catch_warnings():
        warnings.simplefilter("error", DuplicateTrialWarning)
        with pytest.raises(MocapFormatError, match="the same clip id cmu/16_15 as"):
            find_clips([tmp_path])


def test_suffixes_are_found_in_any_case(tmp_path: Path) -> None:
    """WALK.BVH and a .Bvh in a folder are clips; other files are not."""
    for name in ("WALK.BVH", "sub/run.Bvh", "notes.txt", "walk.bvh.part"):
        touch(tmp_path / name)
    found = {s.path.relative_to(tmp_path).as_posix() for s in find_clips([tmp_path])}
    assert found == {"WALK.BVH", "sub/run.Bvh"}


def test_a_file_given_that_is_not_motion_is_refused(tmp_path: Path) -> None:
    """A file named explicitly must be .bvh or .amc; it is never skipped silently."""
    given = touch(tmp_path / "notes.txt")
    with pytest.raises(MocapFormatError, match=r"notes\.txt: not a motion file"):
        find_clips([given])


@pytest.mark.parametrize(
    ("names", "skeleton"),
    [
        (("02.ASF", "02_01.AMC"), "02.ASF"),  # CMU's subject skeleton
        (("TAKEO.ASF", "WALK1.AMC"), "TAKEO.ASF"),  # the folder's only one
        (("walk.ASF", "other.asf", "walk.amc"), "walk.ASF"),  # the clip's own
    ],
)
def test_an_asf_is_found_whatever_the_case_of_its_suffix(
    tmp_path: Path, names: tuple[str, ...], skeleton: str
) -> None:
    """02.ASF is 02_01.AMC's skeleton, as 02.asf is 02_01.amc's."""
    for name in names:
        touch(tmp_path / name)
    assert [s.skeleton for s in find_clips([tmp_path])] == [tmp_path / skeleton]


def test_the_asfs_beside_an_unpaired_amc_are_listed_in_any_case(tmp_path: Path) -> None:
    for name in ("a.ASF", "b.Asf", "walk.AMC"):
        touch(tmp_path / name)
    with pytest.raises(MocapFormatError, match=r"walk\.AMC: no ASF skeleton.*found a\.ASF, b\.Asf"):
        find_clips([tmp_path])


def test_one_file_under_two_spellings_is_one_clip(tmp_path: Path, monkeypatch) -> None:
    """v/ref.bvh and its absolute path (or its folder, or a link to it) name one file: one clip."""
    ref = touch(tmp_path / "v" / "ref.bvh")
    (tmp_path / "link").symlink_to(tmp_path / "v")
    monkeypatch.chdir(tmp_path)
    for given, named in (
        (["v/ref.bvh", ref], "v/ref.bvh"),
        (["v", tmp_path / "v"], "v/ref.bvh"),
        (["./v/ref.bvh", "v", "link"], "v/ref.bvh"),
        ([ref, "v/../v/ref.bvh"], ref),
    ):
        found = find_clips(given)
        assert [(s.clip_id, s.path) for s in found] == [("user/v/ref", Path(named))], given
    # two different files of one clip id are still refused
    touch(tmp_path / "w" / "v" / "ref.bvh")
    with pytest.raises(MocapFormatError, match="the same clip id user/v/ref as"):
        find_clips(["v", "w"])
