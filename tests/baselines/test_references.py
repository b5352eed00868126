"""The reference agents, the leaderboard's hold floor and the validity verdict."""

import gymnasium as gym
import numpy as np
import pytest

import humotion_gym  # noqa: F401
from baselines.agents import REFERENCES, agent_names, make
from baselines.leaderboard import (
    FOLLOW,
    VALID_RATIO,
    compare_to_hold,
    markdown_table,
    run_leaderboard,
    tables,
    validity_lines,
)
from baselines.leaderboard.evaluation import evaluate, run_episode, warm_up
from humotion_gym.body import PARAM_INDEX


def test_hold_answers_the_initial_pose_every_frame():
    env = gym.make("humotion_gym/BodyTrack-v2", terminate_on_lost=False)
    base = env.unwrapped
    agent = make("hold", env)
    obs, info = env.reset(seed=3)
    expected = base.pose_to_action(obs["initial_pose"])
    for k in range(5):
        action, _ = agent.predict(obs, episode_start=np.array([k == 0]))
        assert np.array_equal(action, expected)
        obs, *_, info = env.step(action)
    # a new episode holds its own initial pose
    obs, info = env.reset(seed=4)
    action, _ = agent.predict(obs, episode_start=np.array([True]))
    assert np.array_equal(action, base.pose_to_action(obs["initial_pose"]))


def test_hold_scores_what_the_motion_costs():
    """hold's error at each frame is the distance the scored keypoints moved."""
    env = gym.make("humotion_gym/WalkTrack-v2", terminate_on_lost=False)
    result = run_episode(make("hold", env), env, seed=1)
    assert result.errors_mm[0] < result.errors_mm[-1]  # the walker walks away from it
    assert result.errors_mm[-1] > 300.0


def test_an_environment_that_ends_episodes_on_lost_track_is_refused():
    """Its episodes would stop where track is lost: the mean error would leave out the rest."""
    env = gym.make("humotion_gym/WalkTrack-v2")  # terminate_on_lost=True by default
    with pytest.raises(ValueError, match="terminate_on_lost=False"):
        run_episode(make("hold", env), env, seed=1)


def test_random_agent_is_seeded_and_in_the_action_space():
    env = gym.make("humotion_gym/ArmTrack-v2")
    a, b = make("random", env, seed=2), make("random", env, seed=2)
    obs, info = env.reset(seed=0)
    for _ in range(3):
        x, _ = a.predict(obs)
        y, _ = b.predict(obs)
        assert np.array_equal(x, y) and env.action_space.contains(x)


def test_random_agents_episode_is_its_seed_and_episode_seed_alone():
    env = gym.make("humotion_gym/ArmTrack-v2")
    obs, _ = env.reset(seed=0)
    agent = make("random", env, seed=2)
    for episode_seed in (7, 8, 7):
        agent.seed_episode(episode_seed)
        want = np.random.default_rng([2, episode_seed]).uniform(-1.0, 1.0, 4).astype(np.float32)
        assert np.array_equal(agent.predict(obs)[0], want), episode_seed


def test_agent_names_lists_references_first():
    names = agent_names()
    assert names[: len(REFERENCES)] == list(REFERENCES) and "pf-tree" in names


def test_leaderboard_always_runs_hold_once_per_task_and_compares_to_it():
    rows = run_leaderboard(["SideWalk-v2"], ["pf-cv"], [30, 60], episodes=2, progress=False)
    agents = [(r["agent"], r["particles"]) for r in rows]
    assert agents == [("hold", 0), ("pf-cv", 30), ("pf-cv", 60)]
    table = markdown_table(rows)
    assert "| SideWalk-v2 | hold | - |" in table and "x hold" in table
    ratio, wins, paired = compare_to_hold(rows[1], rows[0])
    assert paired == 2 and 0 <= wins <= 2
    hold_mean = rows[0]["summary"]["mean_error_mm"]
    assert ratio == pytest.approx(hold_mean / rows[1]["summary"]["mean_error_mm"])
    # SideWalk gives the root: the pelvis-aligned error is the error itself.
    for row in rows:
        s = row["summary"]
        assert s["aligned_error_mm"] == pytest.approx(s["mean_error_mm"], rel=1e-9)
        for episode in row["episodes"]:
            assert len(episode["aligned_errors_mm"]) == len(episode["errors_mm"])
    assert f"| {rows[0]['summary']['aligned_error_mm']:.0f} | 1.00 |" in table
    (line,) = validity_lines(rows)
    assert line.startswith("SideWalk-v2: best filter at 30 particles")
    check_verdict(line, ratio)


def check_verdict(line: str, ratio: float) -> None:
    """A validity line ends in the verdict the ratio to hold gives against :data:`VALID_RATIO`.

    Args:
        line: A task's validity line (one agent seed: the best filter's point ratio).
        ratio: The best filter's ratio to hold (:func:`compare_to_hold`).

    Raises:
        AssertionError: If the line's verdict is not the one the ratio gives.
    """
    expected = "valid" if ratio >= VALID_RATIO else f"NOT valid (below {VALID_RATIO:g}x)"
    assert f", {tables.ratio_text(ratio)} in mean error" in line, (line, ratio)
    assert line.endswith(f" paired episodes: {expected}"), (line, ratio)


@pytest.mark.parametrize("errors", [[150.0, 220.0, 130.0], [300.0, 250.0, 280.0]])
def test_the_verdict_check_fails_when_the_rule_is_inverted(monkeypatch, errors):
    """Mutations: a verdict flipped by hand, or by moving the rule's 2x floor past the ratio."""
    hold, tree = _row("hold", 0, [400.0] * 3), _row("pf-tree", 300, errors)
    ratio, _, _ = compare_to_hold(tree, hold)
    (line,) = validity_lines([hold, tree])
    check_verdict(line, ratio)  # the rule as it is: the check passes
    flipped = {"valid": f"NOT valid (below {VALID_RATIO:g}x)"}
    flipped[flipped["valid"]] = "valid"
    head, verdict = line.rsplit(": ", 1)
    with pytest.raises(AssertionError):
        check_verdict(f"{head}: {flipped[verdict]}", ratio)
    # the rule inverted: its floor moved to the other side of this ratio
    monkeypatch.setattr(tables, "VALID_RATIO", ratio * 2 if ratio >= VALID_RATIO else ratio / 2)
    (mutated,) = validity_lines([hold, tree])
    assert mutated.rsplit(": ", 1)[1] != verdict
    with pytest.raises(AssertionError):
        check_verdict(mutated, ratio)


def test_leaderboard_refuses_bad_counts():
    with pytest.raises(ValueError, match="episodes"):
        run_leaderboard(["ArmTrack-v2"], ["hold"], [300], episodes=0, progress=False)
    with pytest.raises(ValueError, match="particles"):
        run_leaderboard(["ArmTrack-v2"], ["pf-cv"], [0], episodes=1, progress=False)


@pytest.mark.parametrize(
    "args, kwargs, error, match",
    [
        ((["ArmTrack-v2"], ["pf-cv"], []), {}, ValueError, "particles: empty, but pf-cv takes"),
        ((["ArmTrack-v2"], ["pf-cv"], [300, 200_000]), {}, ValueError,
         r"particles\[1\]: expected at most 100,000"),
        (([], ["hold"], [30]), {}, ValueError, "tasks: expected at least one"),
        ((["ArmTrack-v2", "Nope-v2"], ["hold"], [30]), {}, ValueError,
         r"tasks\[1\]: unknown task 'Nope-v2'; the tasks are ArmTrack"),
        ((["ArmTrack-v2"], [], [30]), {}, ValueError, "agents: expected at least one"),
        (("ArmTrack-v2", ["hold"], [30]), {}, TypeError, "tasks: expected a list"),
        ((["ArmTrack-v2"], "hold", [30]), {}, TypeError, "agents: expected a list"),
        ((["ArmTrack-v2"], ["hold"], 30), {}, TypeError, "particles: expected a list"),
        ((["ArmTrack-v2"], ["hold"], [30]), {"env_kwargs": "x"}, TypeError, "env_kwargs: expected"),
        ((["ArmTrack-v2"], ["hold"], [30]), {"env_kwargs": {"terminate_on_lost": True}},
         ValueError, "terminate_on_lost is the leaderboard's own"),
    ],
)  # fmt: skip
def test_leaderboard_refuses_a_grid_that_would_drop_or_misread_its_cells(
    args, kwargs, error, match
):
    """particles=[] dropped pf-cv in silence; a task given as a string ran its letters.

    An unknown task raised gymnasium's NameNotFound, not naming ``tasks``, and with
    ``out`` after run.json was written.
    """
    with pytest.raises(error, match=match):
        run_leaderboard(*args, episodes=1, progress=False, **kwargs)
    assert run_leaderboard(["ArmTrack-v2"], ["hold"], [], episodes=1, progress=False)


@pytest.mark.parametrize("episodes", [0, -1, 1.5, "2", True])
def test_evaluate_refuses_what_is_not_a_number_of_episodes(episodes):
    env = gym.make("humotion_gym/ArmTrack-v2", terminate_on_lost=False)
    with pytest.raises(ValueError, match="episodes: expected an integer >= 1"):
        evaluate(make("hold", env), env, episodes)
    with pytest.raises(ValueError, match="agent: expected an agent with predict"):
        evaluate(None, env, 1)


def test_arm_episodes_move_the_arm_in_v1_and_are_not_selected_in_v2():
    """ArmTrack-v1 started only where the elbow and wrist moved 150 mm; v2 keeps every start."""
    with pytest.warns(FutureWarning):
        env = gym.make("humotion_gym/ArmTrack-v1", terminate_on_lost=False)
    base = env.unwrapped
    minimum = base.task.min_motion_mm
    assert minimum == 150.0
    for seed in range(6):
        env.reset(seed=seed)
        moved = base._episode_motion(base._motion)[base._t0]
        assert moved >= minimum
    assert PARAM_INDEX["r_elbow"] in base.task.free_indices
    v2 = gym.make("humotion_gym/ArmTrack-v2").unwrapped
    assert v2.task.min_motion_mm == 0.0


def _row(agent: str, particles: int, errors: list[float]) -> dict:
    return {
        "task": "BodyTrack-v2", "agent": agent, "particles": particles,
        "summary": {"mean_error_mm": float(np.mean(errors))},
        "episodes": [{"seed": k, "mean_error_mm": e} for k, e in enumerate(errors)],
    }  # fmt: skip


def test_validity_compares_the_best_prior_with_pf_follow_where_it_ran():
    hold = _row("hold", 0, [400.0, 400.0, 400.0])
    follow = _row(FOLLOW, 300, [200.0, 210.0, 190.0])
    tree = _row("pf-tree", 300, [150.0, 220.0, 130.0])
    mix = _row("pf-mix", 300, [180.0, 180.0, 180.0])
    many = _row("pf-tree", 3000, [10.0, 10.0, 10.0])  # only the fewest particles count
    verdict, against = validity_lines([hold, follow, tree, mix, many])
    assert verdict.startswith("BodyTrack-v2: best filter at 300 particles is pf-tree")
    assert against == (
        f"BodyTrack-v2: against {FOLLOW} (the body followed, its first articulation held), "
        "the best other filter at 300 particles is pf-tree, 1.20x better in mean error "
        "(167 vs 200 mm), better in 2/3 paired episodes"
    )
    # pf-follow itself the best: no prior beats it, said so.
    worse = _row("pf-tree", 300, [300.0, 300.0, 300.0])
    verdict, against = validity_lines([hold, follow, worse])
    assert "best filter at 300 particles is pf-follow" in verdict
    assert against.startswith(f"BodyTrack-v2: no other filter at 300 particles beats {FOLLOW}")
    assert against.endswith(": the best, pf-tree, 300 vs 200 mm, better in 0/3 paired episodes")
    # Without pf-follow (or with it alone) only the hold verdict.
    assert len(validity_lines([hold, tree])) == 1
    assert len(validity_lines([hold, follow])) == 1


@pytest.mark.parametrize("episode_seed", [-1, 1.7, 1.0, "1", True, None])
def test_an_episode_seed_that_is_not_a_count_is_refused_naming_it(episode_seed):
    """-1 reached numpy's own words; 1.7 seeded episode 1, silently."""
    env = gym.make("humotion_gym/ArmTrack-v2")
    for name, kwargs in [("random", {}), ("pf-cv", {"n_particles": 3, "use_cache": False})]:
        agent = make(name, env, seed=2, **kwargs)
        with pytest.raises(ValueError, match=r"^seed_episode: episode_seed: expected an integer"):
            agent.seed_episode(episode_seed)
        agent.seed_episode(np.int64(3))  # numpy's integers are seeds


def test_a_numpy_seed_runs_the_episodes_a_python_seed_does():
    """np.int64(3) reached gymnasium's reset unconverted: 'Seed must be a python integer'."""
    env = gym.make("humotion_gym/ArmTrack-v2", terminate_on_lost=False)
    hold = make("hold", env)
    want = evaluate(hold, env, 1, seed=3)[0]
    got = evaluate(hold, env, 1, seed=np.int64(3))[0]
    assert got.errors_mm == want.errors_mm and type(got.seed) is int
    assert run_episode(hold, env, np.int64(3)).errors_mm == want.errors_mm
    with pytest.raises(ValueError, match=r"^seed: expected an integer >= 0, got 1.5"):
        run_episode(hold, env, 1.5)


def test_a_predict_that_returns_the_action_alone_is_named():
    """It raised 'too many values to unpack (expected 2)' from the evaluation loop."""

    class ActionOnly:
        def predict(self, obs, state=None, episode_start=None, deterministic=True):
            return np.zeros(4, np.float32)

    env = gym.make("humotion_gym/ArmTrack-v2", terminate_on_lost=False)
    match = r"^agent: ActionOnly.predict must return \(action, state\), as stable-baselines3"
    with pytest.raises(TypeError, match=match + r".*got ndarray$"):
        evaluate(ActionOnly(), env, 1)
    with pytest.raises(TypeError, match=match):
        warm_up(ActionOnly(), env)
