"""Contracts of the CMU index parser, subject ranking and file registry that other tests miss."""

from __future__ import annotations

import hashlib
from pathlib import Path

import pytest

from humotion_gym.mocap._registry import RegistryEntry, load_registry, record_registry
from humotion_gym.mocap.cmu import (
    CmuIndexError,
    cmu_index,
    cmu_label,
    cmu_person,
    parse_cmu_index,
    subjects_by_activity,
)


@pytest.mark.parametrize("text", ["@1 t\n00 walk\n", "@1 t\n00-02 walk\n"])
def test_trial_numbers_start_at_one(text: str) -> None:
    """A trial 0 (alone or opening a range) is refused: CMU numbers trials from 1."""
    with pytest.raises(CmuIndexError, match=r"x\.txt, line 2: .*starts at 0"):
        parse_cmu_index(text, "x.txt")


def test_subjects_by_activity_breaks_ties_by_lower_subject() -> None:
    """Ranked by trial count, ties to the lower number, one number per person (by hand)."""
    ix = cmu_index()
    counts: dict[int, int] = {}
    for s, t in ix.trials:
        if cmu_label(s, t) == "walk":
            counts[s] = counts.get(s, 0) + 1
    # Reference: every (count, subject) pair in the documented order, then the
    # first number of each person.
    want: list[int] = []
    for s in sorted(counts, key=lambda s: (-counts[s], s)):
        if all(cmu_person(s) != cmu_person(k) for k in want):
            want.append(s)
    got = subjects_by_activity(["walk"])
    assert got == want
    # Ties exist here, so the order among equal counts is really tested.
    assert len({counts[s] for s in got}) < len(got)
    # 91 and 105 are one session (one person): the lower number stands for it.
    assert counts[91] == counts[105] and 91 in got and 105 not in got


def test_subjects_by_activity_needs_an_activity() -> None:
    """No activity at all is refused, not answered with an empty list."""
    with pytest.raises(ValueError, match=r"unknown label\(s\) \(none\)"):
        subjects_by_activity([])


# --- the SHA-256 registry of CMU's files --------------------------------------


def entry_line(data: bytes, rel: str) -> str:
    """A registry line for ``data`` saved as ``rel``."""
    return f"{hashlib.sha256(data).hexdigest()} {len(data)} {rel}\n"


@pytest.mark.parametrize(
    "rel",
    [
        "02/03_01.amc",  # a trial filed under another subject's folder
        "02/03.asf",
        "2/2.asf",  # CMU's folders have two or three digits
        "02/02_01.bvh",
    ],
)
def test_registry_names_only_cmu_paths(tmp_path: Path, rel: str) -> None:
    """A line naming anything but SS/SS.asf or SS/SS_TT.amc is refused with its line."""
    reg = tmp_path / "reg.txt"
    reg.write_text("# ok\n" + entry_line(b"x", "02/02_01.amc") + entry_line(b"y", rel))
    with pytest.raises(ValueError, match=r"reg\.txt:3: expected"):
        load_registry(reg)


def test_registry_refuses_a_size_that_is_not_a_count(tmp_path: Path) -> None:
    """A malformed size names the file and line (never a bare int() error)."""
    reg = tmp_path / "reg.txt"
    reg.write_text(entry_line(b"x", "02/02.asf").replace(" 1 ", " -1 "))
    with pytest.raises(ValueError, match=r"reg\.txt:1: expected 'SHA256 BYTES"):
        load_registry(reg)


def test_recording_keeps_the_entries_of_other_files(tmp_path: Path) -> None:
    """record_registry adds to an existing registry: other subjects' entries stay."""
    out = tmp_path / "reg.txt"
    old = b"subject one's skeleton"
    out.write_text(entry_line(old, "01/01.asf"))
    src = tmp_path / "src"
    (src / "02").mkdir(parents=True)
    (src / "02" / "02_01.amc").write_bytes(b"frames")
    entries = record_registry(src, out)
    want = {
        "01/01.asf": RegistryEntry(hashlib.sha256(old).hexdigest(), len(old)),
        "02/02_01.amc": RegistryEntry(hashlib.sha256(b"frames").hexdigest(), 6),
    }
    assert entries == want
    assert load_registry(out) == want
