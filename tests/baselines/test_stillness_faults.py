"""``baselines.stillness``: the scan's bounds and stride, seeds and the table, by hand.

Episodes are replaced by scores made up from their options or seed, so the
choices around them are checked without tracking.
"""

import types

import gymnasium as gym
import pytest

import humotion_gym  # noqa: F401
from baselines.leaderboard.evaluation import EpisodeResult
from baselines.leaderboard.stats import bootstrap_ci
from baselines.stillness import StillWindow, markdown_table


@pytest.fixture(scope="module")
def env():
    return gym.make("humotion_gym/ArmTrack-v2", terminate_on_lost=False)


def test_the_scan_takes_every_strideth_start_and_keeps_a_score_at_the_bound(env, monkeypatch):
    """Starts ``good_starts[::stride]`` of every clip; "at most max_hold_mm" includes it."""
    import baselines.stillness as stillness

    base = env.unwrapped
    scanned = []

    want = [(c.clip_id, int(s)) for c in base.clips for s in base._good_starts(c)[::3]]
    bound = 7.25  # one window scores exactly the bound, every other one above it

    def scored(agent, env_, seed, options):
        scanned.append((options["clip_id"], options["start"]))
        at = (options["clip_id"], options["start"]) == want[1]
        return types.SimpleNamespace(mean_error_mm=bound if at else bound + 1.0)

    monkeypatch.setattr(stillness, "run_episode", scored)
    got = stillness.still_windows(env, max_hold_mm=bound, count=50, stride=3)
    assert scanned == want
    assert got == [StillWindow(want[1][0], want[1][1], bound)]


def test_a_zero_stride_is_refused_by_name(env):
    """stride < 1 is the caller's mistake, named as count's is."""
    import baselines.stillness as stillness

    with pytest.raises(ValueError, match="count and stride"):
        stillness.still_windows(env, stride=0)


def _result(seed: int, mean: float) -> EpisodeResult:
    return EpisodeResult(seed=seed, clip_id="c", start_frame=0, errors_mm=[mean],
                         mean_error_mm=mean, final_error_mm=mean, lost_frame=None,
                         ms_per_frame=1.0, mean_reward=0.0)  # fmt: skip


def test_run_still_seeds_agents_and_episodes_and_judges_at_the_ratio(monkeypatch):
    """Agents seeded ``seed``, episode ``k`` reset with ``seed + k``; exactly 2x hold is within."""
    import baselines.stillness as stillness

    made, ran = [], []

    def fake_make(name, env, n_particles, seed):
        made.append((name, seed))
        return name

    def fake_run(agent, env, seed, options):
        ran.append((agent, seed, options["start"]))
        hold = float(options["start"])  # each window's hold error: its start
        return _result(seed, {"hold": 1.0, "pf-cv": 2.0, "random": 2.5}[agent] * hold)

    monkeypatch.setattr(stillness, "make", fake_make)
    monkeypatch.setattr(stillness, "run_episode", fake_run)
    windows = [StillWindow("a", s, 0.0) for s in (10, 20, 40, 80, 30)]
    out = stillness.run_still("ArmTrack-v2", ["pf-cv", "random"], particles=9,
                              windows=windows, seed=4, progress=False)  # fmt: skip
    assert made == [("hold", 4), ("pf-cv", 4), ("random", 4)]
    assert ran == [(a, 4 + k, w.start) for a in ("hold", "pf-cv", "random")
                   for k, w in enumerate(windows)]  # fmt: skip
    rows = {r["agent"]: r for r in out["rows"]}
    # x_hold as the leaderboard's: hold's error over the row's (pf-cv, twice hold's: 0.5)
    assert rows["hold"]["x_hold"] == 1.0 and rows["hold"]["within"]
    assert rows["pf-cv"]["x_hold"] == pytest.approx(0.5) and rows["pf-cv"]["within"]
    assert rows["random"]["x_hold"] == pytest.approx(0.4) and not rows["random"]["within"]
    errors = [2.0 * w.start for w in windows]
    assert rows["pf-cv"]["mean_error_ci"] == list(bootstrap_ci(errors, seed=4))
    assert bootstrap_ci(errors, seed=4) != bootstrap_ci(errors, seed=0)  # the seed tells
    assert [r["particles"] for r in out["rows"]] == [0, 9, 0]


def test_the_still_table_by_hand():
    """The heading names the count and the bound; each row its error, interval, ratio, verdict.

    The ``/ hold`` column is the row's error over hold's (2.50), ``x_hold``'s inverse.
    """
    result = {
        "task": "ArmTrack-v2", "windows": [{}, {}, {}], "max_hold_mm": 50.0,
        "rows": [
            {"agent": "hold", "particles": 0, "mean_error_mm": 30.4,
             "mean_error_ci": [20.2, 40.6], "x_hold": 1.0, "within": True},
            {"agent": "pf-cv", "particles": 1200, "mean_error_mm": 76.0,
             "mean_error_ci": [60.0, 91.0], "x_hold": 0.4, "within": False},
        ],
    }  # fmt: skip
    lines = markdown_table(result).splitlines()
    assert lines[0] == (
        "ArmTrack-v2: 3 still episodes of the test persons (hold mean error at most 50 mm)"
    )
    assert lines[2] == "| agent | particles | mean error mm (95% CI) | / hold | within 2x hold |"
    assert lines[4] == "| hold | - | 30 (20-41) | 1.00 | yes |"
    assert lines[5] == "| pf-cv | 1,200 | 76 (60-91) | 2.50 | no |"


def test_empty_windows_are_refused_by_name_and_an_empty_search_by_its_bound(monkeypatch):
    """windows=[] said "no episode ... raise max_hold_mm", though no search ran."""
    import baselines.stillness as stillness

    made = []
    monkeypatch.setattr(stillness, "make", lambda name, *args, **kw: made.append(name))
    with pytest.raises(ValueError, match="run_still: windows: expected at least one") as info:
        stillness.run_still("ArmTrack-v2", ["pf-cv"], windows=[], progress=False)
    assert "max_hold" not in str(info.value) and not made
    monkeypatch.setattr(stillness, "still_windows", lambda *args, **kw: [])
    with pytest.raises(ValueError, match="raise max_hold_mm \\(--max-hold\\)"):
        stillness.run_still("ArmTrack-v2", ["pf-cv"], progress=False)
