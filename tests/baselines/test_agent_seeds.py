"""Agent seeds: the two-level bootstrap, the tables and verdicts of several seeds, the runs."""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import pytest

from baselines.cli import main
from baselines.leaderboard import (
    RESULTS_FILE,
    ResumeError,
    markdown_table,
    run_leaderboard,
    validity_lines,
)
from baselines.leaderboard.evaluation import summarize
from baselines.leaderboard.rows import seed_matrix
from baselines.leaderboard.stats import two_level_bootstrap
from baselines.leaderboard.tables import (
    REFERENCE_AGENTS,
    VALID_RATIO,
    compare_to_hold,
    hold_ratio_interval,
    ratio_text,
)

# ------------------------------------------------------------ synthetic rows


def _episodes(values: np.ndarray, several: bool) -> list[dict[str, Any]]:
    """Episode dicts of an ``(episodes, agent seeds)`` matrix of mean errors."""
    out = []
    for a in range(values.shape[1]):
        for s in range(values.shape[0]):
            e = float(values[s, a])
            episode: dict[str, Any] = {"seed": s}
            if several:
                episode["agent_seed"] = a
            episode.update(
                clip_id="synthetic", start_frame=0, errors_mm=[e], mean_error_mm=e,
                final_error_mm=e, lost_frame=None, ms_per_frame=1.0, mean_reward=0.0,
                aligned_errors_mm=[e], mean_aligned_error_mm=e,
            )  # fmt: skip
            out.append(episode)
    return out


def _row(agent: str, particles: int, values: Any, several: bool = True) -> dict[str, Any]:
    v = np.asarray(values, dtype=np.float64)
    episodes = _episodes(v, several)
    return {
        "task": "ArmTrack-v2", "agent": agent, "particles": particles,
        "summary": summarize(episodes), "episodes": episodes,
    }  # fmt: skip


def _hold(n_episodes: int, seeds: int, error: float = 200.0) -> dict[str, Any]:
    return _row("hold", 0, np.full((n_episodes, seeds), error), several=seeds > 1)


# ------------------------------------------------------------ the bootstrap


def _oracle(values: np.ndarray, reference: np.ndarray, n: int, seed: int) -> tuple[Any, Any]:
    """Resample by resample, episode by episode, from the same draws of the generator."""
    rng = np.random.default_rng(seed)
    n_episodes, n_seeds = values.shape
    drawn = rng.integers(n_episodes, size=(n, n_episodes))
    picks = rng.integers(n_seeds, size=(n, n_episodes, n_seeds))
    means, ratios = [], []
    for b in range(n):
        total, held = 0.0, 0.0
        for i in range(n_episodes):
            episode = drawn[b, i]
            total += sum(values[episode, picks[b, i, k]] for k in range(n_seeds)) / n_seeds
            held += reference[episode].mean()
        means.append(total / n_episodes)
        ratios.append(held / total)
    return np.percentile(means, [2.5, 97.5]), np.percentile(ratios, [2.5, 97.5])


@pytest.fixture
def matrix() -> np.ndarray:
    return np.random.default_rng(1).gamma(4.0, 25.0, size=(12, 4))


def test_the_two_level_bootstrap_matches_a_loop_over_resamples(matrix):
    reference = np.full((12, 1), 220.0) + np.arange(12)[:, None]
    mean_ci, ratio_ci = two_level_bootstrap(matrix, reference, n_resamples=300, seed=7)
    want_mean, want_ratio = _oracle(matrix, reference, 300, 7)
    # the same draws summed in another order: equal to rounding (1e-12 relative)
    np.testing.assert_allclose(mean_ci, want_mean, rtol=1e-12)
    np.testing.assert_allclose(ratio_ci, want_ratio, rtol=1e-12)


def test_the_two_level_bootstrap_is_deterministic_in_its_generator(matrix):
    first = two_level_bootstrap(matrix, matrix, seed=np.random.default_rng(3))
    again = two_level_bootstrap(matrix, matrix, seed=np.random.default_rng(3))
    other = two_level_bootstrap(matrix, matrix, seed=4)
    assert first == again
    assert first != other


def test_the_interval_includes_the_seeds_variance():
    # every episode alike: only the agent seeds vary, so only they can widen it
    values = np.tile([80.0, 100.0, 120.0], (10, 1))
    low, high = two_level_bootstrap(values, seed=0)[0]
    assert low < 100.0 < high and high - low > 5.0
    assert two_level_bootstrap(np.full((10, 1), 100.0), seed=0)[0] == (100.0, 100.0)


def test_the_ratio_of_a_reference_twice_the_values_is_two(matrix):
    _, ratio = two_level_bootstrap(matrix[:, :1], 2.0 * matrix[:, :1], seed=0)
    assert ratio == pytest.approx((2.0, 2.0), rel=1e-12)


def test_bad_matrices_are_refused(matrix):
    with pytest.raises(ValueError, match="values"):
        two_level_bootstrap(np.ones(5))
    with pytest.raises(ValueError, match="reference"):
        two_level_bootstrap(matrix, np.ones((3, 1)))
    with pytest.raises(ValueError, match="episodes"):
        seed_matrix(_episodes(matrix, True)[:-1])


def test_a_summary_of_several_seeds_gives_their_means_and_spread(matrix):
    summary = summarize(_episodes(matrix, True))
    means = matrix.mean(axis=0)
    assert summary["agent_seeds"] == 4 and summary["episodes"] == 48
    np.testing.assert_allclose(summary["seed_means_mm"], means, rtol=1e-12)
    assert summary["seed_spread_mm"] == [means.min(), means.max()]
    assert summary["mean_error_mm"] == pytest.approx(matrix.mean(), rel=1e-12)
    assert list(summary["mean_error_ci"]) == list(two_level_bootstrap(matrix, seed=0)[0])
    assert "agent_seeds" not in summarize(_episodes(matrix[:, :1], False))


# ------------------------------------------------------------ tables and verdicts

#: One agent seed: today's table and verdict, character for character.
ONE_SEED_TABLE = """\
| task | agent | particles | mean error mm (95% CI) | IQM mm | pelvis-aligned mm | x hold | beats hold | lost track | ms/frame |
|---|---|---|---|---|---|---|---|---|---|
| ArmTrack-v2 | hold | - | 200 (200-200) | 200 | 200 | 1.00 | - | 0/4 | 1.0 |
| ArmTrack-v2 | pf-cv | 300 | 90 (85-95) | 90 | 90 | 2.22 | 4/4 | 0/4 | 1.0 |"""  # noqa: E501
ONE_SEED_VERDICT = (
    "ArmTrack-v2: best filter at 300 particles is pf-cv, 2.22x better than hold in mean "
    "error (90 vs 200 mm), better in 4/4 paired episodes: valid"
)


def test_one_agent_seed_prints_todays_table_and_verdict():
    rows = [_hold(4, 1), _row("pf-cv", 300, [[85.0], [95.0], [85.0], [95.0]], several=False)]
    assert markdown_table(rows) == ONE_SEED_TABLE
    assert validity_lines(rows) == [ONE_SEED_VERDICT]


def test_several_seeds_add_the_spread_and_the_interval_of_x_hold():
    rows = [_hold(4, 2), _row("pf-cv", 300, [[85.0, 95.0]] * 4)]
    lines = markdown_table(rows).splitlines()
    assert "| mean error mm (95% CI) | seed spread mm | IQM mm |" in lines[0]
    assert lines[1].count("---") == 11
    cells = [c.strip() for c in lines[3].strip("|").split("|")]
    low, high = hold_ratio_interval(rows[1], rows[0])
    assert cells[4] == "85-95" and cells[7] == f"2.22 ({low:.2f}-{high:.2f})"
    assert low < 200 / 90 < high


def _verdict(agent_values: Any, agent: str = "pf-mix") -> str:
    values = np.asarray(agent_values, dtype=np.float64)
    rows = [_hold(values.shape[0], values.shape[1]), _row(agent, 300, values)]
    (line,) = validity_lines(rows)
    return line


def test_a_point_ratio_above_two_with_a_lower_bound_below_is_not_valid():
    """The mutation test: judged on the point ratio (2.22x), this cell would be valid."""
    values = np.array([[30.0, 40.0, 50.0], [130.0, 140.0, 150.0]] * 5)
    rows = [_hold(10, 3), _row("pf-mix", 300, values)]
    low, _ = hold_ratio_interval(rows[1], rows[0])
    assert 200.0 / values.mean() > VALID_RATIO > low
    line = _verdict(values)
    assert line.startswith("ArmTrack-v2: best reference filter at 300 particles is pf-mix")
    assert line.endswith(": NOT valid (interval's lower bound below 2x)")


def test_a_lower_bound_above_two_is_valid():
    values = np.array([[75.0, 80.0, 85.0]] * 10)  # 2.5x, narrow
    assert _verdict(values).endswith(": valid")


def test_the_verdict_is_on_the_reference_agents_alone():
    assert {"pf-mix", "pf-slds", "pf-pca"} <= set(REFERENCE_AGENTS)
    assert "apf-mix" not in REFERENCE_AGENTS
    hold = _hold(6, 2)
    reference = _row("pf-tree", 300, [[150.0, 160.0]] * 6)
    other = _row("apf-mix", 300, [[50.0, 55.0]] * 6)  # better, but not a reference
    (line, *_) = validity_lines([hold, other, reference])
    assert "is pf-tree," in line and line.endswith("NOT valid (interval's lower bound below 2x)")
    assert validity_lines([hold, other]) == []


def _classic(tree: Any, cv: Any, cv_particles: int = 3000) -> list[str]:
    """The verdict lines of a table with hold, pf-tree at 300 and pf-cv at ``cv_particles``."""
    tree_values = np.asarray(tree, dtype=np.float64)
    rows = [
        _hold(*tree_values.shape),
        _row("pf-tree", 300, tree_values),
        _row("pf-cv", cv_particles, cv),
    ]
    return validity_lines(rows)


def test_the_classic_comparison_is_judged_on_its_interval():
    """pf-tree at 300 against pf-cv at 3,000, from the bounds of pf-cv's x pf-tree interval."""
    tree = np.array([[95.0, 100.0, 105.0]] * 10)
    best, classic = _classic(tree, tree * 1.5)
    low, high = hold_ratio_interval(_row("pf-tree", 300, tree), _row("pf-cv", 3000, tree * 1.5))
    assert best.startswith("ArmTrack-v2: best reference filter at 300 particles is pf-tree")
    assert classic == (
        "ArmTrack-v2: pf-tree at 300 particles against pf-cv at 3,000: pf-cv's mean error is "
        f"1.50x pf-tree's (150 vs 100 mm; 95% interval {low:.2f}-{high:.2f}): pf-tree better "
        "(the interval's lower bound above 1)"
    )
    assert 1.0 < low < 1.5 < high
    assert _classic(tree, tree * 0.6)[1].endswith(
        ": pf-cv better (the interval's upper bound below 1)"
    )


def test_a_classic_point_ratio_above_one_spanning_one_is_level():
    """The mutation test: judged on the means (1.05x), pf-tree would be called better."""
    tree = np.array([[60.0, 70.0, 80.0], [140.0, 150.0, 160.0]] * 5)
    cv = np.array([[150.0, 160.0, 170.0], [60.0, 70.0, 80.0]] * 5)
    low, high = hold_ratio_interval(_row("pf-tree", 300, tree), _row("pf-cv", 3000, cv))
    assert cv.mean() / tree.mean() > 1.0 and low < 1.0 < high
    line = _classic(tree, cv)[1]
    assert f"1.05x pf-tree's (115 vs 110 mm; 95% interval {low:.2f}-{high:.2f})" in line
    assert line.endswith(": level within the interval (it spans 1)")


def test_the_classic_result_is_shown_only_at_both_bounds():
    """Shown where the tree beats pf-cv at 300 at the bound and pf-cv at 3,000 is not better."""
    tree = np.array([[95.0, 100.0, 105.0]] * 10)
    hold = _hold(10, 3)

    def line(few: Any, many: Any) -> str:
        rows = [hold, _row("pf-tree", 300, tree), _row("pf-cv", 300, few),
                _row("pf-cv", 3000, many)]  # fmt: skip
        return validity_lines(rows)[1]

    shown = line(tree * 1.5, tree)  # better than 300, level with 3,000
    assert "; against pf-cv at 300: 1.50x (150 mm; 95% interval " in shown
    assert shown.endswith(": shown")
    # The mutations: level with pf-cv at 300, or behind pf-cv at 3,000.
    spread = np.array([[60.0, 70.0, 80.0], [140.0, 150.0, 160.0]] * 5)
    assert line(spread, tree).endswith(": not shown")
    assert line(tree * 1.5, tree * 0.6).endswith(": not shown")


def test_no_classic_line_without_both_of_its_cells():
    tree = np.array([[95.0, 100.0, 105.0]] * 4)
    assert len(_classic(tree, tree * 1.5)) == 2
    assert len(_classic(tree, tree * 1.5, cv_particles=1000)) == 1  # not ten times as many
    hold, cv = _hold(4, 3), _row("pf-cv", 3000, tree * 1.5)
    assert len(validity_lines([hold, _row("pf-mix", 300, tree), cv])) == 1  # no pf-tree


def test_several_seeds_give_the_follow_line_its_interval():
    """pf-follow's line judges the lead at the interval's lower bound, not the means."""
    hold, mix = _hold(10, 3), _row("pf-mix", 300, [[95.0, 100.0, 105.0]] * 10)
    clear = _row("pf-follow", 300, [[145.0, 150.0, 155.0]] * 10)
    spread = np.array([[40.0, 50.0, 60.0], [170.0, 180.0, 190.0]] * 5)  # mean 115: 1.15x
    noisy = _row("pf-follow", 300, spread)
    lines = {}
    for name, follow in (("clear", clear), ("noisy", noisy)):
        *_, line = validity_lines([hold, mix, follow])
        low, high = hold_ratio_interval(mix, follow)
        assert f"; 95% interval {low:.2f}-{high:.2f}: " in line
        lines[name] = (line, low)
    assert lines["clear"][1] > 1.0 and lines["clear"][0].endswith(
        "1.50x better in mean error (100 vs 150 mm; 95% interval "
        f"{lines['clear'][1]:.2f}-{hold_ratio_interval(mix, clear)[1]:.2f}: ahead at the lower "
        "bound), better in 30/30 paired episodes"
    )
    # The mutation: 1.15x better in the means, but the interval reaches below 1.
    assert lines["noisy"][1] < 1.0 and ": level within the interval), " in lines["noisy"][0]
    # Behind pf-follow at the interval's upper bound: not "level".
    (*_, behind) = validity_lines([hold, mix, _row("pf-follow", 300, [[65.0, 70.0, 75.0]] * 10)])
    assert behind.startswith("ArmTrack-v2: no other filter at 300 particles beats pf-follow")
    assert ": behind at the upper bound, better in 0/30 paired episodes" in behind


def test_paired_wins_take_the_references_mean_over_its_seeds():
    """Each (episode, seed) against the reference's mean on that episode, not one of its seeds."""
    follow = _row("pf-follow", 300, [[100.0, 200.0]] * 4)  # 150 on every episode
    row = _row("pf-mix", 300, [[170.0, 140.0]] * 4)
    ratio, wins, paired = compare_to_hold(row, follow)
    assert (wins, paired) == (4, 8)  # 140 < 150 wins, 170 does not
    # Against the reference's last seed (200) both would win: 8 of 8.
    assert ratio == pytest.approx(150.0 / 155.0)
    hold = _hold(4, 2)  # hold's seeds agree: its value itself
    assert compare_to_hold(row, hold)[1:] == (8, 8)


def test_exactly_twice_better_is_valid_at_the_bound():
    """At least 2x: a constant 100 mm against hold's 200 is 2.00x, its interval 2.00-2.00."""
    line = _verdict([[100.0, 100.0, 100.0]] * 6)
    assert "2.00x better than hold" in line and "x hold 95% interval 2.00-2.00): valid" in line
    assert line.endswith(": valid")
    # one agent seed: the point ratio, at least 2x
    rows = [_hold(6, 1), _row("pf-cv", 300, [[100.0]] * 6, several=False)]
    (one,) = validity_lines(rows)
    assert one.endswith("2.00x better than hold in mean error (100 vs 200 mm), better in "
                        "6/6 paired episodes: valid")  # fmt: skip


def test_a_tie_is_level_no_win_and_no_lead():
    """Equal errors: a ratio of exactly 1 is neither better nor worse, and no episode won."""
    same = np.array([[100.0, 100.0, 100.0]] * 4)
    hold, tree = _hold(4, 3), _row("pf-tree", 300, same)
    # the classic comparison at an interval of exactly 1.00-1.00: level, not the tree better
    rows = [hold, tree, _row("pf-cv", 300, same * 1.5), _row("pf-cv", 3000, same)]
    classic = validity_lines(rows)[1]
    assert "1.00x pf-tree's (100 vs 100 mm; 95% interval 1.00-1.00): level within the " in classic
    # better than pf-cv at 300, and pf-cv at 3,000 no better (upper bound 1, at least 1): shown
    assert ": pf-tree better (the interval's lower bound above 1); the classic" in classic
    assert classic.endswith(": shown")
    # a tie wins no paired episode, and is no lead over pf-follow
    assert compare_to_hold(tree, _row("pf-cv", 300, same)) == (1.0, 0, 12)
    flat = [_hold(4, 1), _row("pf-mix", 300, same[:, :1], several=False),
            _row("pf-follow", 300, same[:, :1], several=False)]  # fmt: skip
    assert validity_lines(flat)[-1] == (
        "ArmTrack-v2: no other filter at 300 particles beats pf-follow in mean error: the "
        "best, pf-mix, 100 vs 100 mm, better in 0/4 paired episodes"
    )
    assert ratio_text(1.0) == "1.00x better than hold"


# ------------------------------------------------------------ runs


def _numbers(value: Any) -> Any:
    """Everything but the timings (``ms_per_frame``), which differ run to run."""
    if isinstance(value, dict):
        return {k: _numbers(v) for k, v in value.items() if k != "ms_per_frame"}
    if isinstance(value, list):
        return [_numbers(v) for v in value]
    return value


# Short episodes of small frames: the runs are compared with each other, never with a table.
TINY = {
    "tasks": ["ArmTrack-v2"], "agents": ["pf-cv"], "particles": [50], "episodes": 2,
    "env_kwargs": {"episode_frames": 10, "width": 64, "height": 64},
}  # fmt: skip


@pytest.fixture(scope="module")
def one_seed(tmp_path_factory) -> tuple[list[dict[str, Any]], Any]:
    out = tmp_path_factory.mktemp("one") / "lb"
    return run_leaderboard(**TINY, progress=False, out=out, report=False), out


def test_one_agent_seed_is_the_run_without_the_option(one_seed):
    rows, _ = one_seed
    again = run_leaderboard(**TINY, progress=False, agent_seeds=1)
    assert _numbers(again) == _numbers(rows)
    assert all("agent_seed" not in e for r in rows for e in r["episodes"])
    assert "agent_seeds" not in rows[1]["summary"]


def test_three_agent_seeds_run_the_same_episodes(one_seed):
    rows, out = one_seed
    # resumed from the one-seed run: only agent seeds 1 and 2 run now
    three = run_leaderboard(
        **TINY, progress=False, out=out, resume=True, report=False, agent_seeds=3
    )
    hold, pf = three
    assert [(e["agent_seed"], e["seed"]) for e in pf["episodes"]] == [
        (a, s) for a in range(3) for s in range(2)
    ]
    assert _numbers(pf["episodes"][:2]) == _numbers(
        [{"seed": e["seed"], "agent_seed": 0, **e} for e in rows[1]["episodes"]]
    )
    assert [e["clip_id"] for e in pf["episodes"]] == [e["clip_id"] for e in hold["episodes"]]
    means = pf["summary"]["seed_means_mm"]
    assert len(set(means)) == 3  # the agent seed changes the filter's generator
    assert len({e["mean_error_mm"] for e in hold["episodes"]}) <= 2  # hold has no generator
    saved = json.loads((out / RESULTS_FILE).read_text())
    assert saved["config"]["agent_seeds"] == 3
    (verdict,) = saved["validity"]
    assert verdict.startswith("ArmTrack-v2: best reference filter at 50 particles is pf-cv")
    assert "seed spread mm" in markdown_table(three)
    with pytest.raises(ResumeError, match="agent_seeds=3"):
        run_leaderboard(**TINY, progress=False, out=out, resume=True, report=False)


@pytest.mark.parametrize(
    "extra, message",
    [(["--agent-seeds", "0"], "--agent-seeds"), (["--agent-seeds", "2", "--videos"], "--videos")],
)
def test_the_cli_refuses_bad_agent_seeds(tmp_path, capsys, extra, message):
    argv = ["leaderboard", "--tasks", "ArmTrack-v2", "--agents", "hold", "--episodes", "1"]
    assert main([*argv, "--out", str(tmp_path / "lb"), *extra]) == 2
    assert message in capsys.readouterr().err


def test_the_cli_runs_several_agent_seeds(capsys):
    from baselines.cli.leaderboard import SEEDS_LEGEND

    argv = ["leaderboard", "--tasks", "ArmTrack-v2", "--agents", "pf-cv", "--particles", "20"]
    assert main([*argv, "--episodes", "1", "--agent-seeds", "2"]) == 0
    out = capsys.readouterr().out
    assert "| seed spread mm |" in out and SEEDS_LEGEND in out
    assert "best reference filter at 20 particles is pf-cv" in out


def test_one_episode_or_one_clip_of_one_seed_has_no_interval_and_no_verdict():
    """Resampling one episode (or a declared list's one clip) of one agent seed cannot vary.

    ``leaderboard --episodes 1`` printed "95% interval 0.20-0.20): pf-cv better (the
    interval's upper bound below 1)": a verdict from an interval of zero width.
    """
    rows = [_hold(1, 1), _row("pf-tree", 30, [[245.0]], several=False),
            _row("pf-cv", 300, [[49.0]], several=False)]  # fmt: skip
    assert validity_lines(rows)[1].endswith(
        "pf-cv's mean error is 0.20x pf-tree's (49 vs 245 mm; one episode: no interval): no verdict"
    )
    rows.append(_row("pf-cv", 30, [[25.0]], several=False))
    assert validity_lines(rows)[1].endswith(
        "; against pf-cv at 30: 0.10x (25 mm; one episode: no interval): no verdict; the "
        "classic result (pf-tree better than pf-cv at 30 and no worse than at 300): not "
        "judged (no interval)"
    )
    # three windows of one clip, resampled together: no interval either
    clip = [_hold(3, 1), _row("pf-tree", 30, [[100.0], [120.0], [90.0]], several=False),
            _row("pf-cv", 300, [[60.0], [50.0], [80.0]], several=False)]  # fmt: skip
    for r in clip:
        r["summary"]["intervals"] = "clip"
    assert "(63 vs 103 mm; one clip: no interval): no verdict" in validity_lines(clip)[1]
    # the validity line of several seeds whose best reference ran one episode of one seed
    mixed = [_hold(1, 1), _row("pf-tree", 30, [[50.0]], several=False),
             _row("apf-mix", 30, [[150.0, 160.0]])]  # fmt: skip
    assert validity_lines(mixed)[0].endswith("(50 vs 200 mm; one episode: no interval): no verdict")
    # one episode of two agent seeds: the seeds are resampled, an interval and a verdict
    seeded = [
        _hold(1, 2),
        _row("pf-tree", 30, [[100.0, 140.0]]),
        _row("pf-cv", 300, [[60.0, 65.0]]),
    ]
    assert "95% interval " in validity_lines(seeded)[1]


def test_a_row_and_hold_of_other_episodes_are_refused_not_paired(tmp_path, capsys):
    """One agent seed: ``x hold`` over 4 of hold's 8 episodes divided unpaired means.

    A record keeping 4 of pf-tree's 8 episodes read "1.10 | 2/4"; through
    markdown_table and validity_lines, 2.78x and "valid" where the paired ratio is 1.11.
    """
    errors = np.array([[100.0], [300.0], [100.0], [300.0], [400.0], [500.0], [600.0], [700.0]])
    hold = _row("hold", 0, errors, several=False)
    tree = _row("pf-tree", 100, errors[:4] * 0.9, several=False)
    message = r"ArmTrack-v2: hold: expected the episode seeds \[0, 1, 2, 3\] of pf-tree@100, got "
    for build in (markdown_table, validity_lines):
        with pytest.raises(ValueError, match=message):
            build([hold, tree])
    path = tmp_path / "results.json"
    path.write_text(json.dumps({"seed": 0, "rows": [hold, tree]}))
    assert main(["report", str(path), "--out", str(tmp_path / "report")]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("humotion-gym report: error: ArmTrack-v2: hold: expected the episode")
    assert len(err.splitlines()) == 1


def test_a_value_that_rounds_to_its_threshold_prints_the_digits_that_decide():
    """100.05 mm against hold's 200 is 1.999x: NOT valid, never printed "2.00x ... below 2x".

    The checks compare the values themselves; the lines printed them to 2 decimals, so a
    bound of 1.999 read "2.00-2.00): NOT valid" and 0.9995 "1.00-1.00 ... below 1".
    """
    rows = [_hold(6, 1), _row("pf-cv", 300, [[100.05]] * 6, several=False)]
    (one,) = validity_lines(rows)
    assert "is pf-cv, 1.999x better than hold" in one and one.endswith(": NOT valid (below 2x)")
    seeded = _verdict([[100.05, 100.05]] * 6)
    assert "1.999x better than hold" in seeded
    assert seeded.endswith("x hold 95% interval 1.999-1.999): NOT valid (interval's lower bound "
                           "below 2x)")  # fmt: skip
    tree = np.array([[100.0, 100.0]] * 4)
    classic = _classic(tree, tree * 0.9995)[1]
    assert classic.endswith("(100 vs 100 mm; 95% interval 0.9995-0.9995): pf-cv better (the "
                            "interval's upper bound below 1)")  # fmt: skip
    assert ratio_text(0.9996) == "0.9996x hold: worse than hold"
    assert (
        ratio_text(2.1) == "2.10x better than hold" and ratio_text(1.0) == "1.00x better than hold"
    )
