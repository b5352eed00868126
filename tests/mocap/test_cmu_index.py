"""The packaged CMU trial index, its parser, the activity labels and CMU persons."""

from __future__ import annotations

import re

import pytest

from humotion_gym.mocap.cmu import (
    CMU_SAME_PERSON,
    CMU_TEST_PERSONS,
    CMU_TRIALS_PATH,
    CmuIndexError,
    cmu_index,
    cmu_label,
    cmu_person,
    cmu_test_subjects,
    parse_cmu_index,
    subjects_by_activity,
)
from humotion_gym.mocap.labels import ACTIVITY_LABELS, activity_label, words


def test_index_covers_the_whole_listing():
    ix = cmu_index()
    # CMU's listing: 109 subjects from 1 to 144, 2,435 trials.
    assert len(ix.titles) == 109
    assert len(ix.trials) == 2435
    assert min(ix.titles) == 1 and max(ix.titles) == 144
    # Every subject has trials, numbered without repeats; subjects 40 and 41 start at 2.
    for s in ix.subjects:
        numbers = [t.trial for t in ix.subject_trials(s)]
        assert numbers, s
        assert len(set(numbers)) == len(numbers)
    assert [t.trial for t in ix.subject_trials(40)][0] == 2


def test_index_matches_the_file_line_by_line():
    # An oracle independent of the parser's regexes: count trials from ranges by hand.
    total = 0
    for line in CMU_TRIALS_PATH.read_text(encoding="utf-8").splitlines():
        if not line or line[0] in "#@":
            continue
        first = line.split(" ", 1)[0]
        a, _, b = first.partition("-")
        total += (int(b) if b else int(a)) - int(a) + 1
    assert total == len(cmu_index().trials)


def test_known_descriptions():
    ix = cmu_index()
    assert ix.get(2, 3).description == "run/jog"
    assert ix.get(16, 8).description == "run/jog, sudden stop"
    assert ix.get(143, 25).description == "Waving"
    assert ix.get(35, 99) is None
    assert ix.get(2, 1).key == "02_01" and ix.get(143, 1).key == "143_01"


@pytest.mark.parametrize(
    ("text", "why"),
    [
        ("01 walk\n", "before the first"),
        ("@1 t\n03-02 walk\n", "empty"),
        ("@1 t\n01 walk\n01 run\n", "listed twice"),
        ("@1 t\n@1 u\n", "listed twice"),
        ("@1 t\nwalk\n", "expected"),
    ],
)
def test_parser_errors_name_the_line(text, why):
    with pytest.raises(CmuIndexError, match=rf"x\.txt, line \d+: .*{why}"):
        parse_cmu_index(text, "x.txt")


def test_parser_expands_ranges():
    ix = parse_cmu_index("# c\n@7 walk\n01-03 walk\n04 slow walk\n", "t")
    assert [t.description for t in ix.subject_trials(7)] == ["walk"] * 3 + ["slow walk"]
    assert ix.titles == {7: "walk"}


def test_words_split_camel_case_and_digits():
    assert words("RunningTighterRight") == "running tighter right"
    assert words("Left_Punch_Sequence001") == "left punch sequence 001"
    assert words("LHipJoint") == "l hip joint"
    assert words("high-five, walk") == "high five, walk"


@pytest.mark.parametrize(
    ("text", "label"),
    [
        ("walk on uneven terrain", "walk"),
        ("run/jog", "run"),
        ("RunningStraight", "run"),
        ("Walk to Run", "walk"),
        ("jump, balance", "jump"),
        ("dance - Egyptian walk", "dance"),
        ("dancing bear (human subject)", "pantomime"),
        ("soccer - kick ball", "sports"),
        ("punch/strike", "fight"),
        ("closing a box", "everyday"),
        ("boxing", "fight"),
        ("direct traffic, wave, point", "reach"),
        ("T-Pose", "calibration"),
        ("motorcycle pose", "calibration"),
        ("Unknown", "other"),
        ("cartwheel into backflip", "acrobatics"),
        ("sit on high stool, stand up", "everyday"),
    ],
)
def test_label_rules(text, label):
    assert activity_label(text) == label


def test_every_trial_gets_a_known_label():
    ix = cmu_index()
    labels = {cmu_label(s, t) for s, t in ix.trials}
    assert labels <= set(ACTIVITY_LABELS)
    # The tasks' activities are all present.
    assert {"walk", "run", "jump", "dance", "reach", "everyday", "sports"} <= labels


def test_walk_and_run_words_label_against_the_listing():
    # Every trial whose description names walking (and nothing earlier in the
    # rule order: calibration, a category prefix, pantomime, acrobatics, dance)
    # is a walk; every one naming running and not walking is a run.
    ix = cmu_index()
    early = re.compile(r"danc|salsa| - |human subject|cartwheel|flip|motorcycle|range of motion")
    for (s, t), trial in ix.trials.items():
        text = words(trial.description)
        if early.search(text):
            continue
        if re.search(r"\bwalk", text):
            assert cmu_label(s, t) == "walk", trial
        elif re.search(r"\b(run|jog)", text) and not re.search(r"sneak|march|creep", text):
            assert cmu_label(s, t) == "run", trial


def test_silent_trials_take_the_session_title():
    assert cmu_index().get(107, 1).description == "Unknown"
    assert cmu_label(107, 1) == "walk"  # "Walking with obstacles 1"
    assert cmu_label(94, 3) == "dance"  # "indian dance"
    assert cmu_label(999, 1) == "other"


def test_persons_group_subject_numbers():
    assert cmu_person(2) == "cmu-02"
    assert cmu_person(78) == cmu_person(102) == "cmu-78+102"
    assert cmu_person(111) == cmu_person(113) == cmu_person(114)
    # Pairs recorded together are two people.
    assert cmu_person(18) != cmu_person(19)
    grouped = [s for group, _ in CMU_SAME_PERSON for s in group]
    assert len(grouped) == len(set(grouped)), "a subject in two person groups"


def test_test_persons_cover_walk_run_and_everyday():
    subjects = cmu_test_subjects()
    assert {"cmu-02", "cmu-03"} <= set(subjects)
    numbers = [int(s.split("-")[1]) for s in subjects]
    assert {cmu_person(n) for n in numbers} == set(CMU_TEST_PERSONS)
    labels = {cmu_label(s, t.trial) for s in numbers for t in cmu_index().subject_trials(s)}
    assert {"walk", "run", "everyday", "reach"} <= labels
    # The shared data's training subjects stay in training.
    assert not {"cmu-01", "cmu-05", "cmu-07"} & set(subjects)


def test_subjects_by_activity_ranks_distinct_persons():
    walkers = subjects_by_activity(["walk"])
    counts = {
        s: sum(cmu_label(s, t.trial) == "walk" for t in cmu_index().subject_trials(s))
        for s in walkers
    }
    ranked = [counts[s] for s in walkers]
    assert ranked == sorted(ranked, reverse=True)
    assert len({cmu_person(s) for s in walkers}) == len(walkers)
    top = subjects_by_activity(["walk"], persons=10, exclude_test=True)
    assert len(top) == 10 and not {cmu_person(s) for s in top} & set(CMU_TEST_PERSONS)
    with pytest.raises(ValueError, match="unknown label"):
        subjects_by_activity(["walking"])
    with pytest.raises(ValueError, match="persons"):
        subjects_by_activity(["walk"], persons=0)


def test_a_person_never_straddles_the_split():
    from humotion_gym.mocap.library import CMU_TEST_SUBJECTS, TEST_SUBJECTS

    assert set(CMU_TEST_SUBJECTS) <= TEST_SUBJECTS
    for subjects, evidence in CMU_SAME_PERSON:
        sides = {f"cmu-{s:02d}" in CMU_TEST_SUBJECTS for s in subjects}
        assert len(sides) == 1, (subjects, evidence)
        assert evidence
