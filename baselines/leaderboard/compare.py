"""Two leaderboard runs compared episode by episode: does a rerun reproduce a record?

An episode (:data:`EpisodeKey`) reproduces when its mean keypoint error equals
the record's to ``rtol``. Only the episodes both runs hold are compared, and the
counts say how many each holds. ``humotion-gym compare`` is the command.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from humotion_gym.checks import check_at_least_zero

#: An episode: task, agent, particles, agent seed, episode seed.
EpisodeKey = tuple[str, str, int, int, int]

#: The relative difference two records of one number to 7 significant digits can show.
SAME_RTOL = 5e-7


def episode_means(rows: Sequence[dict[str, Any]], agent_seed: int = 0) -> dict[EpisodeKey, float]:
    """Each episode's mean error (mm) of a run's rows, by :data:`EpisodeKey`.

    ``agent_seed``: that of an episode that names none (the run's ``seed``).

    Raises:
        ValueError: If an episode appears twice.
    """
    out: dict[EpisodeKey, float] = {}
    for row in rows:
        for e in row.get("episodes", []):
            key = (
                str(row["task"]), str(row["agent"]), int(row["particles"] or 0),
                int(e.get("agent_seed", agent_seed)), int(e["seed"]),
            )  # fmt: skip
            if key in out:
                raise ValueError(f"episode {key} appears twice")
            value = e.get("mean_error_mm")
            # null: the strict JSON of a NaN; a number stays, NaN included, and differs
            out[key] = float("nan") if value is None else float(value)
    return out


@dataclass(frozen=True)
class Comparison:
    """What of a rerun reproduces a record.

    Attributes:
        rerun: Episodes the rerun holds.
        recorded: Episodes the record holds.
        compared: Episodes both hold.
        differ: ``(episode, rerun's mm, record's mm)`` of each compared episode
            whose mean error is not the record's.
    """

    rerun: int
    recorded: int
    compared: int
    differ: tuple[tuple[EpisodeKey, float, float], ...]

    def summary(self) -> str:
        """One line: the counts and how many differ."""
        return (
            f"rerun {self.rerun} episodes, record {self.recorded}, compared {self.compared}: "
            f"{len(self.differ)} differ"
        )


def compare_runs(
    rerun: Sequence[dict[str, Any]],
    recorded: Sequence[dict[str, Any]],
    rtol: float = SAME_RTOL,
    agent_seeds: tuple[int, int] = (0, 0),
) -> Comparison:
    """Compare a rerun's episodes with a record's (:func:`episode_means` of each).

    ``agent_seeds``: each run's ``seed``, for its episodes that name none.

    Raises:
        ValueError: If ``rtol`` is not a finite real number >= 0 (a bool or a
            string neither), or a run repeats an episode.
    """
    check_at_least_zero("rtol", rtol)  # a string or a bool too, as a number would not be
    got, want = episode_means(rerun, agent_seeds[0]), episode_means(recorded, agent_seeds[1])
    both = sorted(got.keys() & want.keys())
    # written so that NaN on either side differs (a comparison with NaN is False)
    differ = tuple(
        (k, got[k], want[k]) for k in both if not abs(got[k] - want[k]) <= rtol * abs(want[k])
    )
    return Comparison(len(got), len(want), len(both), differ)
