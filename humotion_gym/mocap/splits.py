"""Who is held out: the test and validation persons, and the split rules.

The benchmark's split is by person. These are the persons each data set holds
out (:data:`TEST_SUBJECTS`, :data:`VALIDATION_SUBJECTS`), the rules the
library reports, and the default rule for a user's own folders
(:func:`user_split`); :mod:`humotion_gym.mocap.library` applies them.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping

from humotion_gym.mocap.cmu import CMU_TEST_PERSONS, cmu_test_subjects

#: CMU subjects held out for testing: every subject number of a test person
#: (:data:`humotion_gym.mocap.cmu.CMU_TEST_PERSONS`). Subject 2 walks, runs,
#: jumps, punches, swings a sword and bends (a bit of everything the tasks
#: track); subject 3 walks on uneven terrain (long walks for the walking tasks);
#: 16 walks and runs straight, veering and turning; 141 and 143 are CMU's
#: "General Subject Capture" sessions (walk, run, jump, everyday motion). Of
#: the shared data (CMU 1, 2, 3, 5, 7) only 2 and 3 are test persons. Their ASF
#: skeletons differ from every training skeleton (checked by
#: :func:`humotion_gym.mocap.persons.check_person_split`).
CMU_TEST_SUBJECTS: tuple[str, ...] = cmu_test_subjects()
#: Synthetic subjects held out for testing.
SYNTHETIC_TEST_SUBJECTS: tuple[str, ...] = ("synthetic-05", "synthetic-06")

#: Every held-out person, whatever the data set. The Bandai-Namco sets are not
#: split: their files do not name the actor and every style of both sets shares
#: one skeleton, so no style can be shown to be another person; all of their
#: clips train. A style held out of them is "style held out, same performers".
TEST_SUBJECTS: frozenset[str] = frozenset(CMU_TEST_SUBJECTS + SYNTHETIC_TEST_SUBJECTS)

#: Training persons held out to choose settings on real data (an environment's
#: ``split="validation"``): CMU subject 1 (jumps) and CMU subjects 5 and 7
#: (dance and walks on one converted skeleton, so they are held out together).
CMU_VALIDATION_SUBJECTS: tuple[str, ...] = ("cmu-01", "cmu-05", "cmu-07")
#: The synthetic set's validation persons (its training persons 3 and 4).
SYNTHETIC_VALIDATION_SUBJECTS: tuple[str, ...] = ("synthetic-03", "synthetic-04")
#: Every validation person, whatever the data set.
VALIDATION_SUBJECTS: frozenset[str] = frozenset(
    CMU_VALIDATION_SUBJECTS + SYNTHETIC_VALIDATION_SUBJECTS
)

#: An environment's splits: whose episodes it shows.
EPISODE_SPLITS: tuple[str, ...] = ("train", "validation", "test")

#: The split rule of each known data set, as the library reports it.
SPLIT_RULES: Mapping[str, str] = {
    "cmu": f"cmu-persons (test persons {', '.join(CMU_TEST_PERSONS)})",
    "bandai-1": "bandai (all train: one skeleton, actors unnamed)",
    "bandai-2": "bandai (all train: one skeleton, actors unnamed)",
    "synthetic": "synthetic (test subjects 05, 06)",
}
#: The default rule for a user's folders (:func:`user_split`).
USER_SPLIT_RULE = "user-hash (1 person in 5 to test, by SHA-256 of the person id)"


def user_split(person: str) -> str:
    """The default split of a user's person: ``"test"`` for one in five, by hash.

    The person's id (its folder name) is hashed with SHA-256 and the person is
    a test person when the hash is 0 modulo 5: stable across runs, machines
    and added folders, and independent of load order.

    Example:
        >>> sorted({user_split(f"actor-{i}") for i in range(20)})
        ['test', 'train']
    """
    digest = int(hashlib.sha256(person.encode("utf-8")).hexdigest(), 16)
    return "test" if digest % 5 == 0 else "train"
