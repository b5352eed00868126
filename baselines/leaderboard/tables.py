"""The leaderboard's tables: each cell against ``hold``, and each task's verdict.

:func:`markdown_table` is the table the README pastes: per cell the mean error
with its interval, the IQM, the pelvis-aligned error, ``x hold`` (``hold``'s
mean error over the row's: above 1 better than doing nothing) and the paired
episodes it beats ``hold`` on. :func:`validity_lines` says per task whether the
best particle filter beats ``hold`` clearly (:data:`VALID_RATIO`) and, where the
table has the cells, judges the tree prior against constant velocity
(:func:`classic_line`) and the best prior's lead over ``pf-follow``
(:func:`follow_line`), each from its ratio's interval (:func:`ratio_verdict`).

Rows of several agent seeds add the spread of the seeds' mean errors, give
``x hold`` its 95% interval (:func:`hold_ratio_interval`), and their task's
verdict takes that interval's lower bound among :data:`REFERENCE_AGENTS`.
:func:`person_rows` and :func:`person_table` break each cell's mean error down
by the person tracked: the test set has few persons.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from baselines.leaderboard.rows import (
    agent_label,
    by_clip,
    cell_label,
    episode_clips,
    ran,
    seed_matrix,
)
from baselines.leaderboard.stats import two_level_bootstrap
from humotion_gym.mocap.cmu import cmu_person
from humotion_gym.mocap.synthetic import synthetic_subject

#: The reference every table shows.
FLOOR = "hold"
#: A task measures tracking when its best particle filter's mean error is at
#: least this many times lower than ``hold``'s (at the smallest particle count).
VALID_RATIO = 2.0
#: The harder reference of the whole-body tasks: the body followed, the first
#: frame's articulation held. Where a table has it, :func:`validity_lines` also
#: says how far the best motion prior is ahead of it.
FOLLOW = "pf-follow"
#: The filters a task's verdict is judged on when its rows have several agent
#: seeds: the particle filters of the four motion priors (constant velocity,
#: the implicit tree with and without velocity, the switching linear model,
#: cyclic PCA) and their mixture. Declared before version 2's tables ran.
REFERENCE_AGENTS: tuple[str, ...] = (
    "pf-cv", "pf-tree", "pf-tree-vel", "pf-slds", "pf-pca", "pf-mix",
)  # fmt: skip
#: Seed of the bootstrap of ``x hold``'s interval (same rows, same interval).
INTERVAL_SEED = 0
#: The classic comparison (Sidenbladh, Black & Sigal 2002): the learned tree
#: prior at a table's fewest particles against constant velocity at ten times
#: as many. Where a table has both, :func:`validity_lines` judges it.
CLASSIC = ("pf-tree", "pf-cv", 10)
# Clip ids that name their person: CMU's trials (``cmu/02_05``, as BVH
# conversions name them too) and the synthetic set's (``synthetic/walk-05``).
_CMU_CLIP = re.compile(r"^cmu/(?:cmu[_-]?)?(\d{1,3})_\d{1,3}")
_SYNTHETIC_CLIP = re.compile(r"^synthetic/.+-(\d+)$")


def seeds_of(row: dict[str, Any]) -> int:
    """How many agent seeds a row that ran has (1 for a row without several)."""
    return int(row.get("summary", {}).get("agent_seeds", 1))


def same_episodes(row: dict[str, Any], reference: dict[str, Any]) -> None:
    """Refuse a reference that did not run exactly the row's episode seeds (it pairs nothing).

    Raises:
        ValueError: Naming the task, both rows and their episode seeds.
    """
    seeds = sorted({int(e["seed"]) for e in row["episodes"]})
    held = sorted({int(e["seed"]) for e in reference["episodes"]})
    if held != seeds:
        raise ValueError(
            f"{row['task']}: {cell_label(reference)}: expected the episode seeds {seeds} of "
            f"{cell_label(row)}, got {held}"
        )


def hold_ratio_interval(
    row: dict[str, Any], hold: dict[str, Any], seed: int = INTERVAL_SEED
) -> tuple[float, float]:
    """95% interval of ``x hold``: ``hold``'s mean over resampled episodes over the row's.

    Both means are over the same resampled episodes; the row's agent seeds
    are resampled within each (:func:`~baselines.leaderboard.stats.two_level_bootstrap`).

    Raises:
        ValueError: If ``hold`` did not run the row's episode seeds.
    """
    same_episodes(row, hold)
    _, _, values = seed_matrix(row["episodes"])
    _, _, reference = seed_matrix(hold["episodes"])
    clusters = episode_clips(row["episodes"]) if by_clip(row) else None  # a declared list
    _, ratio = two_level_bootstrap(values, reference, seed=seed, clusters=clusters)
    assert ratio is not None  # a reference was given
    return ratio


def no_interval(row: dict[str, Any]) -> str | None:
    """Why resampling cannot vary a row's intervals, or None where it can.

    One clip of a declared list, or one episode, of one agent seed gives every
    resample the same value: an interval of zero width decides no verdict.

    Returns:
        ``"one clip"`` or ``"one episode"``, or None.
    """
    episodes, agent_seeds, _ = seed_matrix(row["episodes"])
    if len(agent_seeds) > 1:
        return None
    if by_clip(row):
        return "one clip" if len(set(episode_clips(row["episodes"]))) < 2 else None
    return "one episode" if len(episodes) < 2 else None


def judged_ratio(
    row: dict[str, Any], reference: dict[str, Any], first: str, second: str
) -> tuple[str, tuple[float, float] | None]:
    """The interval of ``reference``'s mean error over ``row``'s and its verdict, as lines say them.

    Returns:
        ``("95% interval LO-HI): VERDICT", (low, high))`` (:func:`hold_ratio_interval`,
        :func:`ratio_verdict` with ``first`` for ``row`` and ``second`` for
        ``reference``), or where resampling cannot vary (:func:`no_interval`)
        ``("one episode: no interval): no verdict", None)``.
    """
    missing = no_interval(row)
    if missing is not None:
        return f"{missing}: no interval): no verdict", None
    low, high = hold_ratio_interval(row, reference)
    bounds = f"{judged_text(low, 1.0)}-{judged_text(high, 1.0)}"
    return f"95% interval {bounds}): {ratio_verdict(low, high, first, second)}", (low, high)


def _floor_of(rows: Sequence[dict[str, Any]], task: str) -> dict[str, Any] | None:
    for r in rows:
        if r["task"] == task and r["agent"] == FLOOR and "summary" in r:
            return r
    return None


def compare_to_hold(row: dict[str, Any], hold: dict[str, Any]) -> tuple[float, int, int]:
    """``hold``'s mean error over the row's, and the paired episodes the row wins.

    Each of the row's episodes (each agent seed's) is paired by episode seed
    with the reference's mean error on it over the reference's agent seeds.

    Returns:
        ``(ratio, wins, paired)``.

    Raises:
        ValueError: If ``hold`` did not run the row's episode seeds (:func:`same_episodes`).
    """
    same_episodes(row, hold)
    ratio = hold["summary"]["mean_error_mm"] / row["summary"]["mean_error_mm"]
    by_seed: dict[Any, list[float]] = {}
    for e in hold["episodes"]:
        by_seed.setdefault(e["seed"], []).append(e["mean_error_mm"])
    held = {seed: values[0] if len(set(values)) == 1 else float(np.mean(values))
            for seed, values in by_seed.items()}  # fmt: skip
    paired = [(e["mean_error_mm"], held[e["seed"]]) for e in row["episodes"] if e["seed"] in held]
    wins = sum(1 for mine, theirs in paired if mine < theirs)
    return float(ratio), wins, len(paired)


def interval(pair: Sequence[float], episodes: int, digits: int = 0) -> str:
    """`` (lo-hi)`` of a 95% interval, or nothing where one episode gives no interval."""
    if episodes < 2:
        return ""
    return f" ({pair[0]:.{digits}f}-{pair[1]:.{digits}f})"


def judged_text(value: float, *thresholds: float) -> str:
    """``value`` to 2 decimals, or to as many more as show it is not a threshold it rounds to.

    A verdict compares the value itself with its threshold: 1.9990 is below
    :data:`VALID_RATIO` and prints ``1.999``, never ``2.00`` beside "below 2x".
    """
    for digits in range(2, 16):
        text = f"{value:.{digits}f}"
        if not any(value != t and text == f"{t:.{digits}f}" for t in thresholds):
            return text
    return repr(value)


def ratio_text(ratio: float, reference: str = FLOOR, thresholds: Sequence[float] = ()) -> str:
    """A ratio of the reference's mean error to a row's, said as what it is.

    ``2.10x better than hold``; below 1, ``0.70x hold: worse than hold`` (the
    row's error is 1/0.70 of the reference's). Printed to 2 decimals, more
    where that would show 1 or one of ``thresholds`` it is not (:func:`judged_text`).
    """
    text = judged_text(ratio, 1.0, *thresholds)
    if ratio >= 1.0:
        return f"{text}x better than {reference}"
    return f"{text}x {reference}: worse than {reference}"


def markdown_rows(table: Sequence[Sequence[str]]) -> str:
    """A Markdown table of a header row then rows of cells (a ``|`` in a cell shown as ``/``)."""
    lines = ["| " + " | ".join(c.replace("|", "/") for c in cells) + " |" for cells in table]
    return "\n".join([lines[0], "|" + "---|" * len(table[0]), *lines[1:]])


def markdown_table(rows: Sequence[dict[str, Any]]) -> str:
    """The leaderboard as a Markdown table, with each row's ratio to ``hold``.

    A cell that did not run shows its reason: ``skipped: ...`` (the agent does
    not cover the task) or ``ERROR: ...`` (it failed). A cell of one episode
    has no interval. Where a row has several agent seeds, a column after the
    mean error gives the spread of the seeds' means and ``x hold`` its 95%
    interval.

    Raises:
        ValueError: If a row did not run its task's ``hold`` episodes (:func:`same_episodes`).
    """
    several = any(seeds_of(r) > 1 for r in rows)
    spread_head, spread_rule = ("| seed spread mm ", "---|") if several else ("", "")
    lines = [
        "| task | agent | particles | mean error mm (95% CI) " + spread_head + "| IQM mm "
        "| pelvis-aligned mm | x hold | beats hold | lost track | ms/frame |",
        "|---|---|---|---|" + spread_rule + "---|---|---|---|---|---|",
    ]
    for r in rows:
        particles = f"{r['particles']:,}" if r["particles"] else "-"
        agent = agent_label(r["agent"])
        if "summary" not in r:  # a cell that did not run: its reason, in the table
            what = f"skipped: {r['skipped']}" if "skipped" in r else f"ERROR: {r.get('error')}"
            what = what.replace("|", "/").replace("\n", " ")
            empty = " |" * (7 if several else 6)
            lines.append(f"| {r['task']} | {agent} | {particles} | {what} |{empty}")
            continue
        s = r["summary"]
        hold = _floor_of(rows, r["task"])
        if hold is None or r is hold:
            ratio, wins = "1.00" if r is hold else "-", "-"
        else:
            x, won, paired = compare_to_hold(r, hold)
            ratio, wins = f"{x:.2f}", f"{won}/{paired}"
            if seeds_of(r) > 1:
                ratio += interval(hold_ratio_interval(r, hold), s["episodes"], 2)
        aligned = s.get("aligned_error_mm")
        aligned_text = "-" if aligned is None else f"{aligned:.0f}"
        mean = f"{s['mean_error_mm']:.0f}{interval(s['mean_error_ci'], s['episodes'])}"
        if several:
            spread = s.get("seed_spread_mm")
            mean += " | -" if spread is None else f" | {spread[0]:.0f}-{spread[1]:.0f}"
        lines.append(
            f"| {r['task']} | {agent} | {particles} | {mean} | {s['iqm_error_mm']:.0f} | "
            f"{aligned_text} | {ratio} | {wins} | "
            f"{round(s['lost_fraction'] * s['episodes'])}/{s['episodes']} | "
            f"{s['ms_per_frame']:.1f} |"
        )
    return "\n".join(lines)


def seeds_verdict(best: dict[str, Any], hold: dict[str, Any], particles: int) -> str:
    """The verdict of a task whose rows have several agent seeds, on the best reference agent.

    Valid only where the lower bound of the 95% interval of ``best``'s ``x
    hold`` (:func:`hold_ratio_interval`) is at least :data:`VALID_RATIO`: a
    point ratio above it whose interval reaches below is NOT valid. Where
    ``best``'s runs give no interval (:func:`no_interval`), no verdict.
    """
    ratio, _, _ = compare_to_hold(best, hold)
    missing = no_interval(best)
    if missing is not None:
        judged = f"{missing}: no interval): no verdict"
    else:
        low, high = hold_ratio_interval(best, hold)
        verdict = (
            "valid"
            if low >= VALID_RATIO
            else f"NOT valid (interval's lower bound below {VALID_RATIO:g}x)"
        )
        bounds = f"{judged_text(low, VALID_RATIO)}-{judged_text(high, VALID_RATIO)}"
        judged = f"x hold 95% interval {bounds}): {verdict}"
    said = ratio_text(ratio, thresholds=[VALID_RATIO])
    return (
        f"best reference filter at {particles:,} particles is {agent_label(best['agent'])}, "
        f"{said} in mean error over {seeds_of(best)} agent seeds "
        f"({best['summary']['mean_error_mm']:.0f} vs {hold['summary']['mean_error_mm']:.0f} mm; "
        f"{judged}"
    )


def ratio_verdict(low: float, high: float, first: str, second: str) -> str:
    """The verdict on ``second``'s mean error over ``first``'s from its interval's bounds.

    ``first`` is better where the lower bound is above 1, ``second`` where the
    upper bound is below 1; otherwise the two are level within the interval.
    """
    if low > 1.0:
        return f"{first} better (the interval's lower bound above 1)"
    if high < 1.0:
        return f"{second} better (the interval's upper bound below 1)"
    return "level within the interval (it spans 1)"


def classic_line(filters: Sequence[dict[str, Any]], fewest: int) -> str | None:
    """The classic comparison of one task's filter rows (:data:`CLASSIC`), or None.

    Constant velocity's mean error over the tree's at ``fewest`` particles
    against ten times as many, with its 95% interval (:func:`judged_ratio`,
    constant velocity in ``hold``'s place) and a verdict from its bounds. Where
    constant velocity also ran at ``fewest``, the same against it, and whether
    the classic result is shown: the tree better at ``fewest`` (lower bound
    above 1) and not worse at ten times as many (upper bound at least 1).
    """
    learned, plain, factor = CLASSIC
    tree = next((r for r in filters if r["agent"] == learned and r["particles"] == fewest), None)
    many = fewest * factor
    cv = next((r for r in filters if r["agent"] == plain and r["particles"] == many), None)
    if tree is None or cv is None:
        return None
    ratio, _, _ = compare_to_hold(tree, cv)
    judged, bounds = judged_ratio(tree, cv, learned, plain)
    line = (
        f"{learned} at {fewest:,} particles against {plain} at {many:,}: {plain}'s mean "
        f"error is {ratio:.2f}x {learned}'s ({cv['summary']['mean_error_mm']:.0f} vs "
        f"{tree['summary']['mean_error_mm']:.0f} mm; {judged}"
    )
    few = next((r for r in filters if r["agent"] == plain and r["particles"] == fewest), None)
    if few is None:
        return line
    ratio2, _, _ = compare_to_hold(tree, few)
    judged2, bounds2 = judged_ratio(tree, few, learned, plain)
    if bounds is None or bounds2 is None:
        shown = "not judged (no interval)"
    else:
        shown = "shown" if bounds2[0] > 1.0 and bounds[1] >= 1.0 else "not shown"
    return (
        f"{line}; against {plain} at {fewest:,}: {ratio2:.2f}x "
        f"({few['summary']['mean_error_mm']:.0f} mm; {judged2}; the classic result ({learned} "
        f"better than {plain} at {fewest:,} and no worse than at {many:,}): {shown}"
    )


def _ranked(row: dict[str, Any]) -> float:
    """A cell's mean error for choosing the best, a NaN mean last (``min`` would keep it first)."""
    mean = float(row["summary"]["mean_error_mm"])
    return mean if np.isfinite(mean) else np.inf


def follow_line(priors: Sequence[dict[str, Any]], follow: dict[str, Any], fewest: int) -> str:
    """How far the best of ``priors`` is ahead of :data:`FOLLOW` at ``fewest`` particles.

    The ratio of the means and the paired episodes won; with several agent
    seeds also the ratio's 95% interval (:func:`hold_ratio_interval`,
    :data:`FOLLOW` in ``hold``'s place): ahead where its lower bound is above 1,
    behind where its upper bound is below 1, level otherwise.
    """
    prior = min(priors, key=_ranked)
    ratio, wins, paired = compare_to_hold(prior, follow)
    means = (
        f"{prior['summary']['mean_error_mm']:.0f} vs {follow['summary']['mean_error_mm']:.0f} mm"
    )
    if seeds_of(prior) > 1:
        low, high = hold_ratio_interval(prior, follow)
        # ratio_verdict's three cases, worded for a lead over the reference.
        ahead = (
            "ahead at the lower bound" if low > 1.0
            else "behind at the upper bound" if high < 1.0
            else "level within the interval"
        )  # fmt: skip
        means += f"; 95% interval {judged_text(low, 1.0)}-{judged_text(high, 1.0)}: {ahead}"
    won = f"better in {wins}/{paired} paired episodes"
    label = agent_label(prior["agent"])
    if ratio > 1.0:
        return (
            f"against {FOLLOW} (the body followed, its first articulation held), the best "
            f"other filter at {fewest:,} particles is {label}, {judged_text(ratio, 1.0)}x better "
            f"in mean error ({means}), {won}"
        )
    return (
        f"no other filter at {fewest:,} particles beats {FOLLOW} in mean error: the best, "
        f"{label}, {means}, {won}"
    )


def validity_lines(rows: Sequence[dict[str, Any]]) -> list[str]:
    """Per task: does the best particle filter beat ``hold`` by :data:`VALID_RATIO`?

    Judged at the smallest particle count run, where the papers' claims are
    made: with one agent seed on the best filter's point ratio; with several,
    on the best of the :data:`REFERENCE_AGENTS` that ran (:func:`seeds_verdict`).
    Then a line for :data:`CLASSIC` (:func:`classic_line`) and one against
    :data:`FOLLOW` (:func:`follow_line`), where the table has their cells.

    Raises:
        ValueError: If a compared row did not run its reference's episodes
            (:func:`same_episodes`).
    """
    out = []
    for task in dict.fromkeys(r["task"] for r in rows):
        hold = _floor_of(rows, task)
        filters = [
            r for r in rows
            if r["task"] == task and "summary" in r and r["particles"] > 0
        ]  # fmt: skip
        if hold is None or not filters:
            continue
        fewest = min(r["particles"] for r in filters)
        at_fewest = [r for r in filters if r["particles"] == fewest]
        if any(seeds_of(r) > 1 for r in at_fewest):
            references = [r for r in at_fewest if r["agent"] in REFERENCE_AGENTS]
            if references:
                best = min(references, key=_ranked)
                out.append(f"{task}: {seeds_verdict(best, hold, fewest)}")
        else:
            best = min(at_fewest, key=_ranked)
            ratio, wins, paired = compare_to_hold(best, hold)
            verdict = "valid" if ratio >= VALID_RATIO else f"NOT valid (below {VALID_RATIO:g}x)"
            out.append(
                f"{task}: best filter at {fewest:,} particles is {agent_label(best['agent'])}, "
                f"{ratio_text(ratio, thresholds=[VALID_RATIO])} in mean error "
                f"({best['summary']['mean_error_mm']:.0f} vs "
                f"{hold['summary']['mean_error_mm']:.0f} mm), better in {wins}/{paired} paired "
                f"episodes: {verdict}"
            )
        classic = classic_line(filters, fewest)
        if classic is not None:
            out.append(f"{task}: {classic}")
        follow = next((r for r in at_fewest if r["agent"] == FOLLOW), None)
        priors = [r for r in at_fewest if r["agent"] != FOLLOW]
        if follow is not None and priors:
            out.append(f"{task}: {follow_line(priors, follow, fewest)}")
    return out


def episode_person(episode: Mapping[str, Any]) -> str | None:
    """Who an episode tracked: its ``person``, else the person its clip id names, else None."""
    person = episode.get("person")
    if person:
        return str(person)
    clip = str(episode.get("clip_id", ""))
    if m := _CMU_CLIP.match(clip):
        return cmu_person(int(m[1]))
    if m := _SYNTHETIC_CLIP.match(clip):
        return synthetic_subject(int(m[1]))
    return None


def person_rows(rows: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per task, agent and person: the episodes and their mean error.

    Only rows that ran, and only their episodes whose person is known
    (:func:`episode_person`); none where no episode names one.

    Returns:
        One dict per (row, person), in the rows' order and persons sorted:
        ``task``, ``agent`` (short label), ``particles``, ``person``,
        ``episodes`` and ``mean_error_mm``.
    """
    out = []
    for r in rows:
        if not ran(r):
            continue
        errors: dict[str, list[float]] = {}
        for e in r.get("episodes", []):
            person = episode_person(e)
            if person is not None:
                errors.setdefault(person, []).append(float(e["mean_error_mm"]))
        for person in sorted(errors):
            out.append(
                {"task": r["task"], "agent": agent_label(r["agent"]),
                 "particles": r["particles"], "person": person,
                 "episodes": len(errors[person]),
                 "mean_error_mm": float(np.mean(errors[person]))}
            )  # fmt: skip
    return out


def person_table(per_person: Sequence[dict[str, Any]]) -> list[list[str]]:
    """:func:`person_rows` as a table: header then one row per cell (empty for no rows).

    One column per person: the mean error in mm with its episodes in parentheses, or ``-``.
    """
    if not per_person:
        return []
    persons = sorted({p["person"] for p in per_person})
    cells: dict[tuple[str, str, Any], dict[str, str]] = {}
    for p in per_person:
        key = (p["task"], p["agent"], p["particles"])
        cells.setdefault(key, {})[p["person"]] = f"{p['mean_error_mm']:.0f} ({p['episodes']})"
    out = [["task", "agent", "particles", *(f"{q} mm (episodes)" for q in persons)]]
    for (task, agent, particles), by in cells.items():
        shown = f"{particles:,}" if particles else "-"
        out.append([task, agent, shown, *(by.get(q, "-") for q in persons)])
    return out
