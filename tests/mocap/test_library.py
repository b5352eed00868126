import json
import os
import time
from pathlib import Path

import numpy as np
import pytest

from baselines.cli import main
from humotion_gym.errors import RigError
from humotion_gym.mocap import library as lib_mod
from humotion_gym.mocap.bvh import load_bvh
from humotion_gym.mocap.export import write_motion_bvh
from humotion_gym.mocap.library import (
    TEST_SUBJECTS,
    MotionLibrary,
    activity_label,
    default_library,
    describe_file,
    find_clips,
    load_library,
    synthetic_library,
)
from humotion_gym.mocap.motion import Motion
from humotion_gym.mocap.retarget import retarget_clip


@pytest.fixture(scope="module")
def synth() -> MotionLibrary:
    """The built-in synthetic library, made once for the module (it is immutable)."""
    return synthetic_library()


def test_default_library_is_synthetic_without_data(monkeypatch):
    monkeypatch.delenv("HUMOTION_MOCAP", raising=False)
    lib = default_library()
    assert lib.is_synthetic and len(lib) >= 30
    assert "synthetic" in lib.table()
    rows = {line.split()[0]: line.split() for line in lib.table().splitlines()[2:-2]}
    for m in lib:
        assert rows[m.clip_id][3] == ("test" if m.subject in lib.held_out else "train")


def test_split_is_by_subject_and_disjoint(synth):
    from humotion_gym.mocap.persons import check_person_split

    lib = synth
    train, test = lib.split("train"), lib.split("test")
    assert len(train) + len(test) == len(lib)
    assert not set(train.subjects) & set(test.subjects)
    assert set(test.subjects) <= TEST_SUBJECTS
    assert check_person_split(lib).test_persons == tuple(test.subjects)
    with pytest.raises(ValueError, match="train"):
        lib.split("validation")


def test_lookup_filter_and_errors(synth):
    lib = synth
    m = lib["synthetic/walk-01"]
    assert m.label == "walk"
    assert all(x.label == "run" for x in lib.filter(labels=["run"]))
    with pytest.raises(KeyError, match="no clip"):
        lib["nope"]


def test_filtering_a_fold_keeps_its_held_out_subjects(synth):
    fold = synth.validation_fold(["synthetic-01"])
    walks = fold.filter(labels=["walk"])
    assert walks.held_out == fold.held_out == frozenset({"synthetic-01"})
    assert walks.split("test").subjects == ["synthetic-01"]
    assert "synthetic-01" not in walks.split("train").subjects
    assert fold.filter(subjects=["synthetic-02"]).held_out == frozenset({"synthetic-01"})


def test_split_by_mapping_looks_up_clip_then_subject_then_person(tmp_path):
    from humotion_gym.mocap.library import ClipSource, assign_split

    src = ClipSource(
        tmp_path / "w.bvh", None, "user", "anna-day2", "walk", "", "user/anna-day2/w", "anna"
    )
    assert assign_split(src, {"anna": "test"}) == ("test", "split_by mapping (anna)")
    assert assign_split(src, {"anna": "test", "anna-day2": "train"}) == (
        "train",
        "split_by mapping (anna-day2)",
    )
    assert assign_split(src, {"user/anna-day2/w": "test", "anna-day2": "train"})[0] == "test"


def test_motion_save_load_round_trip(tmp_path, synth):
    m = synth["synthetic/reach-03"]
    m.save(tmp_path / "m.npz")
    back = Motion.load(tmp_path / "m.npz")
    assert back.clip_id == m.clip_id and back.shape == m.shape and back.synthetic
    assert np.array_equal(back.params, m.params) and np.array_equal(back.observed, m.observed)
    with pytest.raises(ValueError, match="not a saved Motion"):
        (tmp_path / "bad.npz").write_bytes(b"junk")
        Motion.load(tmp_path / "bad.npz")


@pytest.mark.parametrize(
    "name, dataset, subject, label",
    [
        ("dataset-1_walk-back_proud_003.bvh", "bandai-1", "bandai-1/proud", "walk-back"),
        ("dataset-2_run_masculine_012.bvh", "bandai-2", "bandai-2/masculine", "run"),
        ("02_03.amc", "cmu", "cmu-02", "run"),
        ("07_01.bvh", "cmu", "cmu-07", "walk"),
        ("35_17.bvh", "cmu", "cmu-35", "run"),
        ("cmu_16_11.bvh", "cmu", "cmu-16", "walk"),
        ("143_25_poses.bvh", "cmu", "cmu-143", "reach"),
        ("13_99.bvh", "cmu", "cmu-13", "other"),
        ("my_take.bvh", "user", "x", "other"),
    ],
)
def test_file_descriptions(tmp_path, name, dataset, subject, label):
    folder = tmp_path / "x"
    folder.mkdir()
    src = describe_file(folder / name)
    assert (src.dataset, src.subject, src.label) == (dataset, subject, label)


def test_a_users_clip_is_the_same_person_however_its_path_is_written(tmp_path, monkeypatch):
    # Person and split come from the folder: "take.bvh" named from inside
    # "anna" is anna's, as "anna/take.bvh" and the absolute path are.
    folder = tmp_path / "anna"
    folder.mkdir()
    monkeypatch.chdir(folder)
    ways = [Path("take.bvh"), Path("./take.bvh"), folder / "take.bvh", Path("../anna/take.bvh")]
    described = {(s.subject, s.person, s.clip_id) for s in map(describe_file, ways)}
    assert described == {("anna", "anna", "user/anna/take")}


def test_activity_labels():
    assert activity_label("walk on uneven terrain") == "walk"
    assert activity_label("run/jog") == "run"
    assert activity_label("dance - sideways arabesque") == "dance"
    assert activity_label("playground - forward jumps, turn around") == "jump"


def _write_clip(folder, name, motion):
    path = folder / name
    write_motion_bvh(path, motion.params, motion.shape, motion.fps)
    return path


def test_cache_is_used_and_rebuilt_when_the_file_changes(tmp_path, monkeypatch, synth):
    data, cache = tmp_path / "data", tmp_path / "cache"
    data.mkdir()
    walk = synth["synthetic/walk-01"]
    path = _write_clip(data, "take.bvh", walk)
    (data / "partial.bvh.part").write_text("not a clip")  # partial downloads are ignored
    first = load_library([data], cache_dir=cache, progress=False)
    assert len(first) == 1 and len(list((cache / "clips").glob("*.npz"))) == 1

    calls = []
    real_load = lib_mod.load_clip
    monkeypatch.setattr(lib_mod, "load_clip", lambda *a, **k: calls.append(a) or real_load(*a, **k))
    second = load_library([data], cache_dir=cache, progress=False)
    assert calls == [] and np.array_equal(second[0].params, first[0].params)

    run = synth["synthetic/run-01"]
    time.sleep(0.01)
    _write_clip(data, "take.bvh", run)
    os.utime(path, ns=(time.time_ns(), time.time_ns() + 10**9))
    third = load_library([data], cache_dir=cache, progress=False)
    assert len(calls) == 1
    assert not np.array_equal(third[0].params, first[0].params)


def test_missing_paths_and_orphan_amc(tmp_path):
    with pytest.raises(FileNotFoundError, match="no such file"):
        find_clips([tmp_path / "absent"])
    (tmp_path / "09_01.amc").write_text(":DEGREES\n")
    with pytest.raises(ValueError, match="no ASF skeleton"):
        find_clips([tmp_path])


def test_load_clip_names_its_argument_when_given_a_path():
    # A path failed inside with "'str' object has no attribute 'skeleton'".
    with pytest.raises(TypeError, match=r"^load_clip: src: expected a ClipSource .*find_clips"):
        lib_mod.load_clip("empty.bvh")


def test_cli_data_table_and_convert(tmp_path, capsys):
    assert main(["data", "table"]) == 0
    assert "synthetic" in capsys.readouterr().out
    out = tmp_path / "skip.bvh"
    assert main(["data", "convert", "synthetic/skip-02", str(out)]) == 0
    assert out.is_file()
    assert main(["data", "info", str(out), "--json"]) == 0
    row = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert row["rig"] == "cone-body" and row["error_max_mm"] < 1e-3


# -- real data -------------------------------------------------------------------


@pytest.mark.mocap
def test_every_shared_clip_loads(real_library, shared_mocap):
    files = [p for p in shared_mocap.rglob("*") if p.suffix in (".bvh", ".amc")]
    assert len(real_library) == len(files) > 500
    datasets = {m.dataset for m in real_library}
    assert datasets == {"cmu", "bandai-1", "bandai-2"}
    rigs = {m.meta["rig"] for m in real_library}
    assert rigs == {"cmu-asf", "character-creator", "bandai"}
    for m in real_library:
        assert np.all(np.isfinite(m.params)) and m.fps == 30.0


@pytest.mark.mocap
def test_retargeting_error_on_real_data_is_small(real_library):
    # Limbs follow the source exactly; the error is the rigid torso against a
    # bending spine, and one symmetric shape per clip (see retarget.py).
    for dataset, bound in (("cmu", 15.0), ("bandai-1", 8.0), ("bandai-2", 8.0)):
        errs = np.concatenate([m.retarget_error() for m in real_library if m.dataset == dataset])
        assert np.nanmean(errs) < bound, dataset
        assert np.nanmax(errs) < 100.0, dataset


@pytest.mark.mocap
def test_real_splits_hold_out_persons(real_library):
    # Held out by person, verified from the skeletons, not only by the names
    # that define the split: no test subject's skeleton is in the training data.
    from humotion_gym.mocap.persons import check_person_split

    test = real_library.split("test")
    train = real_library.split("train")
    assert set(test.subjects) == {"cmu-02", "cmu-03"}
    assert all(s in train.subjects for s in real_library.subjects if s.startswith("bandai-"))
    report = check_person_split(real_library)
    assert report.test_persons == tuple(test.subjects)
    assert report.train_persons == tuple(train.subjects)
    assert len(test.filter(labels=["walk"])) >= 5 and len(train.filter(labels=["walk"])) >= 20


@pytest.mark.mocap
def test_poses_on_real_data_stay_within_the_joint_limits(real_library):
    from humotion_gym.body import ANGLE_MASK, PARAM_LOWER, PARAM_UPPER

    params = np.concatenate([m.params for m in real_library])
    params[:, ANGLE_MASK] = (params[:, ANGLE_MASK] + np.pi) % (2 * np.pi) - np.pi
    outside = (params < PARAM_LOWER) | (params > PARAM_UPPER)
    assert outside.mean(axis=0).max() < 0.001


@pytest.mark.parametrize(
    ("frames", "why"),
    [
        ("Frames: 0\nFrame Time: 0.0083333\n", r"the file holds no frame of motion \(Frames: 0\)"),
        ("NAN", "none of its 2 frames is whole"),
    ],
)
def test_a_clip_without_a_whole_frame_is_refused_naming_its_file(
    shared_mocap, tmp_path, frames, why
):
    text = (shared_mocap / "cmu-bvh-cc" / "007" / "007_01.bvh").read_text()
    head, _, motion = text.partition("MOTION\n")
    if frames == "NAN":  # two frames, every number of them nan
        width = len(motion.splitlines()[2].split())
        frames = "Frames: 2\nFrame Time: 0.0083333\n" + ("nan " * width + "\n") * 2
    (tmp_path / "empty.bvh").write_text(head + "MOTION\n" + frames)
    with pytest.raises(RigError, match=r"empty\.bvh: nothing to retarget: " + why):
        load_library([tmp_path], progress=False)
    clip = load_bvh(tmp_path / "empty.bvh")  # retargeting alone says the same
    with pytest.raises(RigError, match=why):
        retarget_clip(clip, units_to_mm=10.0)


def test_one_path_alone_is_a_path_and_a_folder_named_like_a_clip_is_not_one(shared_mocap, tmp_path):
    folder = tmp_path / "data"
    (folder / "decoy.bvh").mkdir(parents=True)
    clip = shared_mocap / "cmu-asfamc" / "02" / "02_01.amc"
    (folder / "02.asf").write_bytes((clip.parent / "02.asf").read_bytes())
    (folder / "02_01.amc").write_bytes(clip.read_bytes())
    for given in (str(folder), folder):
        assert [m.clip_id for m in load_library(given, progress=False)] == ["cmu/02_01"]


def test_an_amc_is_never_read_on_another_subjects_lone_asf(shared_mocap, tmp_path):
    """03_01.amc beside 02.asf alone is refused, not read as subject 3 on subject 2's skeleton."""
    from humotion_gym.errors import MocapFormatError

    source = shared_mocap / "cmu-asfamc"
    (tmp_path / "02.asf").write_bytes((source / "02" / "02.asf").read_bytes())
    (tmp_path / "02_01.amc").write_bytes((source / "02" / "02_01.amc").read_bytes())
    (tmp_path / "03_01.amc").write_bytes((source / "03" / "03_01.amc").read_bytes())
    with pytest.raises(MocapFormatError, match=r"03_01\.amc: no ASF skeleton of its subject.*"
                       r"expected 03_01\.asf, 03\.asf or one ASF alone; found 02\.asf"):  # fmt: skip
        find_clips([tmp_path])
    (tmp_path / "03_01.amc").unlink()
    (tmp_path / "walk.amc").write_bytes((source / "02" / "02_02.amc").read_bytes())
    assert len(find_clips([tmp_path])) == 2  # a name of no subject takes the folder's one ASF


def test_each_amc_takes_the_asf_of_its_own_name(shared_mocap, tmp_path):
    """walk.asf beside walk.amc and run.asf beside run.amc: one skeleton per clip."""
    source = shared_mocap / "cmu-asfamc"
    for stem, subject in (("walk", "02"), ("run", "03")):
        (tmp_path / f"{stem}.asf").write_bytes((source / subject / f"{subject}.asf").read_bytes())
        (tmp_path / f"{stem}.amc").write_bytes(
            (source / subject / f"{subject}_01.amc").read_bytes()
        )
    found = {src.path.name: src.skeleton.name for src in find_clips([tmp_path])}
    assert found == {"walk.amc": "walk.asf", "run.amc": "run.asf"}


def test_linked_folders_are_read_once_and_a_linked_file_is_its_own_clip(shared_mocap, tmp_path):
    """A symlinked folder's clips are found (a loop is followed once); a link caches apart."""
    import warnings

    from humotion_gym.mocap.library import CacheWarning

    source = shared_mocap / "cmu-asfamc" / "03"
    top = tmp_path / "data"
    top.mkdir()
    (top / "subj03").symlink_to(source, target_is_directory=True)
    (top / "subj03again").symlink_to(source, target_is_directory=True)
    (top / "loop").symlink_to(top, target_is_directory=True)
    found = [s.clip_id for s in find_clips([top])]
    assert found == sorted({f"cmu/{p.stem}" for p in source.glob("*.amc")})
    walk = shared_mocap / "bandai-1" / "dataset-1_walk_normal_001.bvh"
    alone = tmp_path / "alone"
    (alone / "dave").mkdir(parents=True)
    (alone / "dave" / "walk.bvh").symlink_to(walk)
    cache = tmp_path / "cache"
    with warnings.catch_warnings():
        warnings.simplefilter("error", CacheWarning)  # the link and its target cache apart
        for _ in range(2):
            load_library([walk], progress=False, cache_dir=cache)
            load_library([alone], progress=False, cache_dir=cache)


@pytest.mark.parametrize(
    "paths, fps, error, match",
    [
        (None, 30.0, TypeError, "paths must be a path or paths, got None"),
        (5, 30.0, TypeError, "paths must be a path or paths, got 5"),
        ([1], 30.0, TypeError, r"paths must be a path or paths, got \[1\]"),
        ([], 0, ValueError, "fps must be None or a positive frame rate, got 0"),
        ([], float("nan"), ValueError, "fps must be None or a positive frame rate"),
    ],
)
def test_load_library_refuses_what_is_not_paths_or_a_frame_rate(paths, fps, error, match):
    with pytest.raises(error, match=f"load_library: {match}"):
        load_library(paths, fps=fps, progress=False)


def test_load_library_reads_an_iterator_of_paths_once(tmp_path):
    assert len(load_library(iter([tmp_path]), progress=False)) == 0
