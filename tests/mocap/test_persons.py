"""Held-out persons verified from skeletons (humotion_gym.mocap.persons)."""

import dataclasses
import json

import numpy as np
import pytest

from baselines.cli import main
from humotion_gym.body import KEYPOINT_INDEX
from humotion_gym.mocap.library import (
    CMU_TEST_SUBJECTS,
    SYNTHETIC_TEST_SUBJECTS,
    TEST_SUBJECTS,
    MotionLibrary,
    load_library,
    synthetic_library,
)
from humotion_gym.mocap.persons import (
    DEFAULT_ATOL_MM,
    DEFAULT_RTOL,
    SIGNATURE_NAMES,
    SIGNATURE_SIZE,
    TEST_SKELETONS_FILE,
    SplitError,
    check_data_persons,
    check_person_split,
    held_out_skeletons_of,
    held_out_subjects,
    known_test_pairs,
    same_skeleton,
    skeleton_difference,
    skeleton_groups,
    skeleton_owner,
    skeleton_signature,
    subject_skeletons,
)

BANDAI_STYLES_OLD_TEST = ("bandai-2/masculine", "bandai-1/masculinity")


@pytest.fixture(scope="module")
def synth() -> MotionLibrary:
    return synthetic_library()


def _renamed(library: MotionLibrary, clip_id: str, subject: str, new_id: str) -> MotionLibrary:
    copy = dataclasses.replace(library[clip_id], subject=subject, clip_id=new_id)
    return MotionLibrary((*library.motions, copy))


# -- signatures and tolerances (no shared data) ----------------------------------


def test_signature_is_the_rigid_bones_of_the_shape(synth):
    m = synth["synthetic/walk-01"]
    sig = skeleton_signature(m)
    assert sig.shape == (SIGNATURE_SIZE,) == (len(SIGNATURE_NAMES),)
    s = m.shape
    want = [2 * s.hip_half_width] + [
        v for v in (s.upper_arm_length, s.forearm_length, s.thigh_length, s.shin_length)
        for _ in range(2)
    ]  # fmt: skip
    np.testing.assert_allclose(sig, want, atol=1e-6)


def test_signature_is_stable_within_a_subject_and_ignores_unobserved_frames(synth):
    walk, wave = synth["synthetic/walk-03"], synth["synthetic/wave-03"]
    assert skeleton_difference(walk, wave) < 1e-9
    kp = walk.keypoints.copy()
    kp[::2] = np.nan  # half the frames unobserved
    kp[:, KEYPOINT_INDEX["r_wrist"]] = np.nan  # one bone never observed: shape's length
    gappy = dataclasses.replace(walk, keypoints=kp)
    np.testing.assert_allclose(skeleton_signature(gappy), skeleton_signature(walk), atol=1e-6)


def test_same_skeleton_tolerances(synth):
    sig = skeleton_signature(synth["synthetic/walk-01"])
    assert same_skeleton(sig, sig.copy())
    # every bone 1.5 % longer: within 2 % + 1 mm, not within 1 %
    longer = sig * 1.015
    assert same_skeleton(sig, longer) and same_skeleton(longer, sig)
    assert not same_skeleton(sig, longer, rtol=0.01, atol_mm=0.0)
    # one bone 5 mm off is a different skeleton with no relative tolerance
    one = sig.copy()
    one[3] += 5.0
    assert not same_skeleton(sig, one, rtol=0.0, atol_mm=1.0)
    assert same_skeleton(sig, one, rtol=0.0, atol_mm=5.5)
    assert skeleton_difference(sig, one) == pytest.approx(5.0 / one[3])
    with pytest.raises(ValueError, match="tolerances"):
        same_skeleton(sig, sig, rtol=-0.1)
    with pytest.raises(ValueError, match="signature of 9"):
        same_skeleton(sig[:4], sig[:4])


def test_same_skeleton_tolerance_is_relative_to_the_longer_bone_and_inclusive():
    base = np.full(SIGNATURE_SIZE, 100.0)
    # 2.02 mm on a 100 mm bone: within 2 % of 102.02 mm (2.0404), not of 100 mm (2.0)
    off = base.copy()
    off[5] = 102.02
    assert same_skeleton(base, off, rtol=0.02, atol_mm=0.0)
    assert same_skeleton(off, base, rtol=0.02, atol_mm=0.0)
    assert not same_skeleton(base, off, rtol=0.0197, atol_mm=0.0)  # 2.0098 mm
    # a bone exactly at the tolerance matches (|a - b| <= tol)
    edge = base.copy()
    edge[0] = 105.0
    assert same_skeleton(base, edge, rtol=0.0, atol_mm=5.0)
    assert not same_skeleton(base, edge, rtol=0.0, atol_mm=4.999)


def test_distinct_synthetic_subjects_are_distinct_skeletons(synth):
    # The default tolerance stays well under the closest two synthetic people.
    sigs = {s.subject: s.signature for s in subject_skeletons(synth)}
    names = sorted(sigs)
    diffs = [
        skeleton_difference(sigs[a], sigs[b]) for i, a in enumerate(names) for b in names[i + 1 :]
    ]
    assert min(diffs) > 2 * (DEFAULT_RTOL + DEFAULT_ATOL_MM / 200.0)  # 1 mm of a 200 mm bone
    assert skeleton_groups(synth) == [(s,) for s in names]
    assert all(s.spread_mm < 1e-6 for s in subject_skeletons(synth))


def test_synthetic_split_passes(synth):
    report = check_person_split(synth)
    assert report.test_persons == SYNTHETIC_TEST_SUBJECTS
    assert set(report.train_persons) == set(synth.subjects) - set(SYNTHETIC_TEST_SUBJECTS)
    assert report.min_difference > DEFAULT_RTOL
    assert report.closest_pair[0] in SYNTHETIC_TEST_SUBJECTS
    assert "person split OK" in str(report)


def test_a_copied_motion_under_another_name_is_caught(synth):
    # A test person's clip relabelled as a new training subject: the names
    # still split cleanly, the skeletons do not.
    lib = _renamed(synth, "synthetic/walk-05", "synthetic-99", "synthetic/walk-99")
    assert "synthetic-99" in lib.split("train").subjects
    with pytest.raises(SplitError, match="synthetic-05 ~ synthetic-99") as info:
        check_person_split(lib)
    assert info.value.pairs == (("synthetic-05", "synthetic-99"),)
    assert isinstance(info.value, ValueError)
    assert ("synthetic-05", "synthetic-99") in skeleton_groups(lib)


def test_a_copy_among_a_training_subject_s_own_clips_is_caught(synth):
    """One name over two skeletons: each of its clips is compared, not only the first."""
    lib = _renamed(synth, "synthetic/walk-05", "synthetic-01", "synthetic/walk-01b")
    own = {s.subject: s for s in subject_skeletons(lib)}["synthetic-01"]
    assert own.clips == len(synth.filter(subjects=["synthetic-01"])) + 1 and own.spread_mm > 5
    with pytest.raises(SplitError, match="synthetic-05 ~ synthetic-01") as info:
        check_person_split(lib)
    assert info.value.pairs == (("synthetic-05", "synthetic-01"),)


def test_skeleton_owner_names_the_subject_whose_skeleton_a_clip_has(synth):
    train = synth.split("train")
    walk = synth["synthetic/walk-03"]
    renamed = dataclasses.replace(walk, subject="who", clip_id="user/who/w")
    assert skeleton_owner(renamed, train) == "synthetic-03"
    bigger = dataclasses.replace(renamed, keypoints=walk.keypoints * 1.05)  # 4.8 % longer bones
    assert skeleton_owner(bigger, train) is None
    assert skeleton_owner(bigger, train, rtol=0.06) == "synthetic-03"
    assert skeleton_owner(synth["synthetic/walk-05"], train) is None  # a test person
    assert skeleton_owner(walk, MotionLibrary(())) is None


def test_a_test_persons_copy_is_caught_without_the_test_persons_files(synth):
    """Only the renamed copy is loaded: the packaged skeletons still know whose it is."""
    copy = dataclasses.replace(synth["synthetic/walk-05"], subject="dave", clip_id="user/dave/w")
    alone = MotionLibrary((copy,))
    assert alone.held_out.isdisjoint({"dave"}) and known_test_pairs(alone) == [
        ("synthetic-05", "dave")
    ]
    with pytest.raises(SplitError, match=r"^library: .*\(synthetic-05 ~ dave\)"):
        check_data_persons(alone)
    # the training persons' own clips match no held-out skeleton
    assert known_test_pairs(synth.split("train")) == []
    check_data_persons(synth)


def test_a_library_s_own_held_out_subjects_are_checked(synth):
    """A validation fold holds out its own subjects, not TEST_SUBJECTS."""
    fold = synth.validation_fold(["synthetic-01"])
    assert held_out_subjects(fold) == frozenset({"synthetic-01"})
    report = check_person_split(fold)
    assert report.test_persons == ("synthetic-01",)
    assert "synthetic-01" not in report.train_persons
    # a copy of the fold's held-out subject under a training name is caught
    copy = dataclasses.replace(synth["synthetic/walk-01"], subject="synthetic-97", clip_id="c/97")
    leaky = MotionLibrary((*fold.motions, copy), fold.test_subjects)
    with pytest.raises(SplitError, match="synthetic-01 ~ synthetic-97"):
        check_person_split(leaky)
    assert held_out_subjects(MotionLibrary(())) == TEST_SUBJECTS


def test_a_test_persons_skeleton_on_the_test_side_is_no_leak(synth):
    """A known held-out skeleton under a name that is itself held out trains nothing."""
    copy = dataclasses.replace(synth["synthetic/walk-05"], subject="dave", clip_id="user/dave/w")
    alone = MotionLibrary((copy,), TEST_SUBJECTS | {"dave"})
    assert known_test_pairs(alone) == []
    check_data_persons(alone)


def test_tolerance_decides_a_rescaled_copy(synth):
    # The same motion on a skeleton 5 % larger is another person at the default
    # tolerance, the same one at a 6 % tolerance.
    src = synth["synthetic/walk-06"]
    big = dataclasses.replace(
        src, subject="synthetic-98", clip_id="synthetic/big-98", keypoints=src.keypoints * 1.05
    )
    lib = MotionLibrary((*synth.motions, big))
    assert check_person_split(lib).min_difference == pytest.approx(0.05 / 1.05, rel=1e-6)
    with pytest.raises(SplitError, match="synthetic-06 ~ synthetic-98"):
        check_person_split(lib, rtol=0.06)


def test_explicit_test_subjects_and_empty_sides(synth):
    report = check_person_split(synth, test_subjects={"synthetic-01", "absent-person"})
    assert report.test_persons == ("synthetic-01",)
    nothing = check_person_split(synth, test_subjects=set())
    assert nothing.test_persons == () and nothing.closest_pair is None
    assert np.isinf(nothing.min_difference)
    empty = check_person_split(MotionLibrary(()))
    assert empty.test_persons == empty.train_persons == ()


def test_cli_data_persons_on_synthetic(capsys):
    assert main(["data", "persons"]) == 0
    out = capsys.readouterr().out
    assert "synthetic-05" in out and "person split OK" in out
    assert main(["data", "persons", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["split_ok"] is True
    rows = {r["subject"]: r for r in doc["subjects"]}
    assert rows["synthetic-05"]["split"] == "test" and rows["synthetic-01"]["split"] == "train"
    assert set(rows["synthetic-01"]["signature_mm"]) == set(SIGNATURE_NAMES)
    assert rows["synthetic-01"]["same_skeleton_as"] == []


def test_cli_data_persons_refuses_what_an_environment_refuses(tmp_path, capsys):
    """A test person's clip converted into a training person's folder: exit 1, as gym.make.

    zed and amy are training persons (user_split); zed's walk is synthetic-05's,
    a held-out person whose own files are not loaded: only the packaged
    skeletons know it (check_data_persons, which the environments run).
    """
    for clip, person in (("synthetic/walk-05", "zed"), ("synthetic/walk-01", "amy")):
        (tmp_path / person).mkdir()
        assert main(["data", "convert", clip, str(tmp_path / person / "walk.bvh")]) == 0
    capsys.readouterr()
    with pytest.raises(SplitError, match="synthetic-05 ~ zed"):
        check_data_persons(load_library([tmp_path], progress=False), [tmp_path])
    assert main(["data", "persons", str(tmp_path)]) == 1
    captured = capsys.readouterr()
    assert "zed" in captured.out and "person split OK" not in captured.out
    assert (
        captured.err.count("\n") == 1
        and (
            "person split fails: a held-out person's skeleton is also a training person's "
            "(synthetic-05 ~ zed; synthetic-05: by the package's record of its skeleton)"
        )
        in captured.err
    )
    assert main(["data", "persons", str(tmp_path), "--json"]) == 1
    doc = json.loads(capsys.readouterr().out)
    assert doc["split_ok"] is False and "synthetic-05 ~ zed" in doc["message"]
    # a held-out set given with --test is that set's check alone
    assert main(["data", "persons", str(tmp_path), "--test", "amy"]) == 0


# -- real data ---------------------------------------------------------------------


@pytest.mark.mocap
def test_current_split_passes_on_the_shared_data(real_library):
    report = check_person_split(real_library)
    # The shared data holds CMU 1, 2, 3, 5 and 7: of the test persons only 2 and 3.
    assert report.test_persons == ("cmu-02", "cmu-03")
    assert set(report.test_persons) <= set(CMU_TEST_SUBJECTS)
    assert not set(report.train_persons) & TEST_SUBJECTS
    # Every Bandai style trains; the closest training skeleton is still far off.
    assert {s for s in report.train_persons if s.startswith("bandai-")} == {
        s for s in real_library.subjects if s.startswith("bandai-")
    }
    assert report.min_difference > 0.05


@pytest.mark.mocap
def test_the_packaged_test_skeletons_are_those_of_the_shared_data(real_library, synth):
    packaged = json.loads(TEST_SKELETONS_FILE.read_text())
    assert packaged["names"] == list(SIGNATURE_NAMES)
    made = {**held_out_skeletons_of(real_library), **held_out_skeletons_of(synth)}
    assert packaged["skeletons"] == made
    assert known_test_pairs(real_library) == []  # no training person of the data is one


@pytest.mark.mocap
def test_real_skeletons_group_into_persons(real_library):
    groups = skeleton_groups(real_library)
    bandai = tuple(s for s in real_library.subjects if s.startswith("bandai-"))
    assert len(bandai) >= 19
    assert groups[0] == bandai  # one skeleton for every style of both sets
    assert ("cmu-05", "cmu-07") in groups  # one Character-Creator skeleton
    for single in ("cmu-01", "cmu-02", "cmu-03"):
        assert (single,) in groups
    # Rigid bones: constant over every clip of a subject (float32 keypoints).
    assert max(s.spread_mm for s in subject_skeletons(real_library)) < 0.01


@pytest.mark.mocap
def test_old_split_holding_out_bandai_styles_fails(real_library):
    old = {"cmu-02", *BANDAI_STYLES_OLD_TEST, *SYNTHETIC_TEST_SUBJECTS}
    with pytest.raises(SplitError, match="person split fails") as info:
        check_person_split(real_library, test_subjects=old)
    message = str(info.value)
    assert "bandai-2/masculine ~ bandai-2/normal" in message
    assert "bandai-1/masculinity ~ bandai-1/normal" in message
    held = {pair[0] for pair in info.value.pairs}
    assert held == set(BANDAI_STYLES_OLD_TEST)  # cmu-02 itself is a distinct person
    # each held-out style matches every training style of both sets
    train_styles = {s for s in real_library.subjects if s.startswith("bandai-")} - held
    for style in BANDAI_STYLES_OLD_TEST:
        assert {t for h, t in info.value.pairs if h == style} == train_styles


@pytest.mark.mocap
def test_holding_out_cmu_07_alone_fails(real_library):
    with pytest.raises(SplitError, match="cmu-07 ~ cmu-05") as info:
        check_person_split(real_library, test_subjects={"cmu-07"})
    assert info.value.pairs == (("cmu-07", "cmu-05"),)


@pytest.mark.mocap
def test_cli_data_persons_on_the_shared_data(shared_mocap, shared_loads_are_the_sessions, capsys):
    assert main(["data", "persons", str(shared_mocap)]) == 0
    out = capsys.readouterr().out
    assert "person split OK" in out and "G2, one skeleton: cmu-05, cmu-07" in out
    code = main(["data", "persons", str(shared_mocap), "--test", "bandai-2/masculine", "--json"])
    assert code == 1
    captured = capsys.readouterr()
    doc = json.loads(captured.out)
    assert doc["split_ok"] is False and "bandai-2/masculine ~ bandai-1/normal" in doc["message"]
    assert "bandai-2/masculine ~" in captured.err
    # one line on stderr, as every error of the command line
    assert captured.err.count("\n") == 1 and captured.err.startswith("humotion-gym data persons:")
