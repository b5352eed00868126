"""The CMU Graphics Lab Motion Capture Database: every trial, its label and its person.

The package ships CMU's description of every trial (``data/cmu_trials.txt``,
the facts of CMU's public listing in the project's own compact format; see its
header). :func:`cmu_index` parses it once; :func:`cmu_label` labels any CMU
trial by its description (:func:`humotion_gym.mocap.labels.activity_label`,
falling back on the subject's session title when the trial's own text says
nothing); :func:`cmu_person` says which person a subject number is, and
:data:`CMU_TEST_PERSONS` which persons the benchmark holds out.

Persons (evidence in ``docs/data.md``): CMU numbers *sessions*, not people. The
listing's own notes and trial lists give the groups of :data:`CMU_SAME_PERSON`,
each one person or possibly one person, always kept on one side of the split.
Pairs recorded together (18/19, 20/21, 22/23, 33/34: "2 subjects - subject A/B")
are two *different* people in one session: separate persons. Subjects' ASF
skeletons tell people apart (:mod:`humotion_gym.mocap.persons`, ``humotion-gym
data persons``).
"""

from __future__ import annotations

import functools
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

from humotion_gym.mocap.labels import ACTIVITY_LABELS, activity_label, says_nothing

#: The packaged trial descriptions.
CMU_TRIALS_PATH = Path(__file__).resolve().parent / "data" / "cmu_trials.txt"

#: Subject numbers that are one person (or cannot be shown to be two), each
#: with the evidence; every other subject number is a person of its own.
CMU_SAME_PERSON: tuple[tuple[tuple[int, ...], str], ...] = (
    ((78, 102), "the same basketball session under two numbers (same trial names in order)"),
    ((91, 105), "the same session of walks, turns and jumps under two numbers (62 trials)"),
    ((93, 103), "the same Charleston session under two numbers (8 trials)"),
    ((111, 113, 114), "one participant: 'Pregnant Woman' (111, 114), 'Post pregnant woman' (113)"),
)

#: CMU persons held out for testing. 2 and 3 are the shared data's test persons;
#: 16 walks and runs (straight, veering, turning; 58 trials), 141
#: and 143 are CMU's two "General Subject Capture" sessions (run, jump, walk,
#: sit, pick up, throw, wave, punch: everyday motion), held out together so
#: that the split holds whether or not they are one person.
CMU_TEST_PERSONS: tuple[str, ...] = ("cmu-02", "cmu-03", "cmu-16", "cmu-141", "cmu-143")


class CmuIndexError(ValueError):
    """The trial index file is malformed (names the file and line)."""


@dataclass(frozen=True)
class CmuTrial:
    """One CMU trial.

    Attributes:
        subject: CMU subject (session) number.
        trial: Trial number within the subject.
        description: CMU's description ("Unknown" when CMU gives none).
    """

    subject: int
    trial: int
    description: str

    @property
    def key(self) -> str:
        """``"SS_TT"`` as in CMU's file names (``"02_01"``, ``"143_07"``)."""
        return f"{self.subject:02d}_{self.trial:02d}"


@dataclass(frozen=True)
class CmuIndex:
    """Every CMU trial with its subject's session title.

    Attributes:
        titles: Subject number -> CMU's description of the session.
        trials: ``(subject, trial)`` -> the trial, in file order.
    """

    titles: Mapping[int, str]
    trials: Mapping[tuple[int, int], CmuTrial]

    @property
    def subjects(self) -> list[int]:
        """Subject numbers, ascending."""
        return sorted(self.titles)

    def subject_trials(self, subject: int) -> list[CmuTrial]:
        """A subject's trials by trial number (empty for an unknown subject)."""
        return sorted(
            (t for (s, _), t in self.trials.items() if s == subject), key=lambda t: t.trial
        )

    def get(self, subject: int, trial: int) -> CmuTrial | None:
        """The trial, or None when the listing does not have it."""
        return self.trials.get((subject, trial))


_SUBJECT_LINE = re.compile(r"^@(\d{1,3}) (\S.*)$")
_TRIAL_LINE = re.compile(r"^(\d{1,3})(?:-(\d{1,3}))? (\S.*)$")


def parse_cmu_index(text: str, source: str = "<text>") -> CmuIndex:
    """Parse the compact trial index (format in the data file's header).

    Args:
        text: The file's text.
        source: Its name, for error messages.

    Returns:
        The index.

    Raises:
        CmuIndexError: On a malformed line, a trial before any subject, a
            range whose end precedes its start, or a repeated subject or trial;
            the message names ``source`` and the line.
    """
    titles: dict[int, str] = {}
    trials: dict[tuple[int, int], CmuTrial] = {}
    subject: int | None = None
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.rstrip()
        where = f"{source}, line {number}"
        if not line or line.startswith("#"):
            continue
        m = _SUBJECT_LINE.match(line)
        if m:
            subject = int(m[1])
            if subject in titles:
                raise CmuIndexError(f"{where}: subject {subject} listed twice")
            titles[subject] = m[2].strip()
            continue
        m = _TRIAL_LINE.match(line)
        if not m:
            raise CmuIndexError(
                f"{where}: expected '@SS title', 'TT description' or 'TT-UU description', "
                f"got {line[:60]!r}"
            )
        if subject is None:
            raise CmuIndexError(f"{where}: a trial before the first '@SS' subject line")
        first = int(m[1])
        last = int(m[2]) if m[2] else first
        if last < first or first < 1:
            raise CmuIndexError(f"{where}: trial range {first}-{last} is empty or starts at 0")
        for t in range(first, last + 1):
            if (subject, t) in trials:
                raise CmuIndexError(f"{where}: trial {subject:02d}_{t:02d} listed twice")
            trials[(subject, t)] = CmuTrial(subject, t, m[3].strip())
    return CmuIndex(titles, trials)


@functools.lru_cache(maxsize=1)
def cmu_index() -> CmuIndex:
    """The packaged index of every CMU trial (parsed once)."""
    return parse_cmu_index(CMU_TRIALS_PATH.read_text(encoding="utf-8"), str(CMU_TRIALS_PATH))


def cmu_subject_id(subject: int) -> str:
    """The library's subject id of a CMU subject number: ``"cmu-02"``, ``"cmu-143"``."""
    return f"cmu-{subject:02d}"


@functools.lru_cache(maxsize=1)
def _person_of() -> dict[int, str]:
    out: dict[int, str] = {}
    for subjects, _ in CMU_SAME_PERSON:
        person = "cmu-" + "+".join(f"{s:02d}" for s in sorted(subjects))
        for s in subjects:
            out[s] = person
    return out


def cmu_person(subject: int) -> str:
    """The person of a CMU subject number.

    A subject of a group in :data:`CMU_SAME_PERSON` is the group's person
    (``"cmu-78+102"``); any other subject is its own person, whose id equals
    its subject id (``"cmu-02"``).
    """
    return _person_of().get(subject, cmu_subject_id(subject))


def cmu_test_subjects() -> tuple[str, ...]:
    """Every CMU subject id of a test person (a person's every number), sorted."""
    test = set(CMU_TEST_PERSONS)
    numbers = set(cmu_index().titles) | set(_person_of())
    return tuple(cmu_subject_id(s) for s in sorted(numbers) if cmu_person(s) in test)


def cmu_label(subject: int, trial: int, description: str | None = None) -> str:
    """The activity label of a CMU trial.

    Args:
        subject: Subject number.
        trial: Trial number.
        description: The description to use; the packaged index's when None.

    Returns:
        The label of the trial's description; where that says nothing
        ("Unknown", "clean", "bad AMC": :func:`~humotion_gym.mocap.labels.says_nothing`),
        the label of the subject's session title ("Walking with obstacles" ->
        walk); ``"other"`` for a trial the index does not know. A description
        the rules do not know ("OffensiveMoveSpinLeft") stays ``"other"``.
    """
    index = cmu_index()
    if description is None:
        description = cmu_description(subject, trial)
    label = activity_label(description) if description else "other"
    if says_nothing(description) and subject in index.titles:
        title = activity_label(index.titles[subject])
        if title != "calibration":
            label = title
    return label


def cmu_description(subject: int, trial: int) -> str:
    """CMU's description of a trial, or ``""`` when the index does not know it."""
    known = cmu_index().get(subject, trial)
    return known.description if known is not None else ""


def subjects_by_activity(
    activities: Iterable[str], persons: int | None = None, exclude_test: bool = False
) -> list[int]:
    """CMU subject numbers that performed the activities, most trials first.

    Subjects are ranked by how many of their trials carry one of the labels
    (ties: lower subject number first); one subject per person, so the list
    names distinct people (the other numbers of a person are left out).

    Args:
        activities: Labels (:data:`humotion_gym.mocap.labels.ACTIVITY_LABELS`).
        persons: How many persons to return (all when None).
        exclude_test: Leave out the test persons (:data:`CMU_TEST_PERSONS`).

    Returns:
        Subject numbers.

    Raises:
        ValueError: If an activity is not a known label or ``persons`` < 1.
    """
    wanted = set(activities)
    unknown = sorted(wanted - set(ACTIVITY_LABELS))
    if unknown or not wanted:
        raise ValueError(f"activity: unknown label(s) {unknown or '(none)'}; use {ACTIVITY_LABELS}")
    if persons is not None and persons < 1:
        raise ValueError(f"persons: need at least 1, got {persons}")
    counts: dict[int, int] = {}
    for (s, t), _ in cmu_index().trials.items():
        if cmu_label(s, t) in wanted:
            counts[s] = counts.get(s, 0) + 1
    ranked = sorted(counts, key=lambda s: (-counts[s], s))
    out: list[int] = []
    seen: set[str] = set()
    for s in ranked:
        person = cmu_person(s)
        if person in seen or (exclude_test and person in CMU_TEST_PERSONS):
            continue
        seen.add(person)
        out.append(s)
        if persons is not None and len(out) == persons:
            break
    return out
