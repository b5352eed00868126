"""The clips of the SLDS experiments: loading, the activities' labels, train and test persons."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

from baselines.experiments.pavlovic1999.settings import CLASSIFY_LABELS, LABEL_ALIASES
from humotion_gym.mocap.library import (
    TEST_SUBJECTS,
    MotionLibrary,
    default_library,
    load_library,
)
from humotion_gym.mocap.motion import Motion


def activity_clips(
    motions: Sequence[Motion],
    labels: Sequence[str] = CLASSIFY_LABELS,
    aliases: dict[str, str] | None = None,
) -> list[Motion]:
    """The clips of the classified activities, with aliased labels folded in.

    Args:
        motions: Any clips.
        labels: The activities kept.
        aliases: Label renames applied first (:data:`LABEL_ALIASES` when None:
            Bandai-Namco set 1's ``dash`` is running).

    Returns:
        The clips whose (renamed) label is in ``labels``, in their order.
    """
    aliases = LABEL_ALIASES if aliases is None else aliases
    out = []
    for m in motions:
        label = aliases.get(m.label, m.label)
        if label in labels:
            out.append(m if label == m.label else dataclasses.replace(m, label=label))
    return out


def load_motions(paths: Sequence[str]) -> list[Motion]:
    """Every clip under the files or folders, at 30 Hz."""
    return list(load_library(paths, fps=30.0, progress=False))


def default_motions(data_dir: Sequence[str] | None) -> list[Motion]:
    """The default library's clips (``data_dir``, else ``$HUMOTION_MOCAP``, else synthetic)."""
    return list(default_library(data_dir or None, fps=30.0, progress=False))


def person_split(motions: Sequence[Motion]) -> tuple[list[Motion], list[Motion]]:
    """The clips of training persons and those of test persons."""
    lib = MotionLibrary(tuple(motions))
    return list(lib.split("train")), list(lib.split("test"))


def split_train_test(
    train: Sequence[Motion], test: Sequence[Motion]
) -> tuple[list[Motion], list[Motion]]:
    """Clip sets that share a clip id are split by person; disjoint ones are kept.

    When the two sets share a clip id, training uses the train split of
    ``train`` and testing the test split of ``test``
    (:meth:`~humotion_gym.mocap.library.MotionLibrary.split`). ``slds
    classify`` refuses a file reached by both ``--train`` and ``--test``, so
    there only different files of one clip id reach this split (a copy of a
    trial in another folder, ``02_01.amc`` and ``02_01.bvh``); the same clips
    given twice come only from the Python API.

    Raises:
        ValueError: If overlapping sets leave no test clip (no test person in ``test``).
    """
    if {m.clip_id for m in train} & {m.clip_id for m in test}:
        train_split, test_split = person_split(train)[0], person_split(test)[1]
        if not test_split:
            raise ValueError(
                "--train and --test overlap, so they are split by person, but --test has no clip "
                f"of a test person ({sorted(TEST_SUBJECTS)}); give --test disjoint clips or a "
                "folder with the test persons (e.g. ../shared/mocap)"
            )
        return train_split, test_split
    return list(train), list(test)
