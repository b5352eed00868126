import importlib.util
import json

import gymnasium as gym
import numpy as np
import pytest

import humotion_gym  # noqa: F401
from baselines.agents import AGENTS, TaskNotSupported, make
from baselines.agents.base import describe, episode_begins
from baselines.agents.filters import body_part_stages
from baselines.agents.settings import load as load_settings
from baselines.cli import main
from baselines.leaderboard import evaluation
from baselines.leaderboard.evaluation import evaluate, run_episode, summarize, warm_up
from baselines.leaderboard.stats import bootstrap_ci, iqm, stratified_bootstrap_ci
from humotion_gym.body import CONE_NAMES
from humotion_gym.envs.description import pose_to_action, read_observation


class RandomPolicy:
    """An SB3-shaped policy: the loop gives it observations and nothing else."""

    def __init__(self, space, seed=0):
        self.space, self.rng = space, np.random.default_rng(seed)

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        return self.rng.uniform(-1, 1, self.space.shape).astype(np.float32), state


def test_registry_and_unknown_agent():
    assert "pf-cv" in AGENTS
    env = gym.make("humotion_gym/ArmTrack-v2")
    with pytest.raises(KeyError, match="unknown agent"):
        make("pf-nothing", env)


@pytest.mark.parametrize(
    "kwargs",
    [{"n_particles": 2.5}, {"n_particles": "300"}, {"n_particles": 0}, {"n_particles": True},
     {"seed": -1}, {"seed": "a"}, {"seed": 1.0}, {"n_particles": 100_001}],
)  # fmt: skip
def test_make_refuses_counts_that_are_not_integers_naming_them(kwargs):
    env = gym.make("humotion_gym/ArmTrack-v2")
    name = next(iter(kwargs))
    for agent in ("pf-cv", "hold"):
        with pytest.raises(ValueError, match=f"agents.make: {name}: expected an integer"):
            make(agent, env, **kwargs)
    make("pf-cv", env, n_particles=np.int64(10), seed=np.int32(3))


def test_make_refuses_what_is_not_a_name_a_task_or_a_likelihood():
    env = gym.make("humotion_gym/ArmTrack-v2")
    for name in (None, 5):
        with pytest.raises(TypeError, match="agents.make: name must be an agent's name"):
            make(name, env)
    for task in (None, "ArmTrack-v2"):
        with pytest.raises(TypeError, match="expected a humotion_gym pose-tracking environment"):
            make("pf-cv", task)
    with pytest.raises(TypeError, match="observation_model must have prepare"):
        make("pf-cv", env, observation_model="x")


def test_a_vector_envs_batch_is_refused_saying_so():
    env = gym.make("humotion_gym/ArmTrack-v2")
    obs, _ = env.reset(seed=0)
    batch = {key: np.stack([value, value]) for key, value in obs.items()}
    for name in ("hold", "pf-cv"):
        with pytest.raises(ValueError, match=r"a batch of 2 \(a vector env's\).*make_batch"):
            make(name, env, n_particles=20).predict(batch, episode_start=True)


def test_particle_filter_agent_tracks_end_to_end_on_synthetic_data():
    env = gym.make("humotion_gym/SideWalk-v2", terminate_on_lost=False)
    agent = make("pf-cv", env, n_particles=200, seed=0)
    result = run_episode(agent, env, seed=0)
    assert len(result.errors_mm) == 60 and np.isfinite(result.mean_error_mm)
    # tracking beats guessing: a random policy on the same episode does far worse
    rand = run_episode(RandomPolicy(env.action_space), env, seed=0)
    assert result.mean_error_mm < 0.5 * rand.mean_error_mm


def test_agent_runs_are_deterministic_by_seed():
    env = gym.make("humotion_gym/ArmTrack-v2", terminate_on_lost=False)
    a = evaluate(make("pf-cv", env, n_particles=100, seed=3), env, 2, seed=5)
    b = evaluate(make("pf-cv", env, n_particles=100, seed=3), env, 2, seed=5)
    assert [r.errors_mm for r in a] == [r.errors_mm for r in b]


def test_agent_refuses_what_is_not_a_v2_observation():
    env = gym.make("humotion_gym/ArmTrack-v2")
    agent = make("pf-cv", env, n_particles=10)
    obs, _ = env.reset(seed=0)
    with pytest.raises(ValueError, match="version-2"):
        agent.predict(obs["frame"])
    with pytest.raises(ValueError, match="version-2"):
        agent.predict({k: v for k, v in obs.items() if k != "camera"})


def test_summary_and_statistics():
    env = gym.make("humotion_gym/ArmTrack-v2", terminate_on_lost=False)
    results = evaluate(RandomPolicy(env.action_space), env, 3, seed=0)
    s = summarize(results)
    assert (
        s["episodes"] == 3 and s["mean_error_ci"][0] <= s["mean_error_mm"] <= s["mean_error_ci"][1]
    )
    assert iqm([1, 2, 3, 4, 100, -100, 2.5, 3.5]) == pytest.approx(np.mean([2, 2.5, 3, 3.5]))
    lo, hi = bootstrap_ci(np.arange(100.0))
    assert lo < 49.5 < hi
    lo2, hi2 = stratified_bootstrap_ci(np.arange(40.0).reshape(20, 2))
    assert lo2 < hi2


class _Scores(gym.Wrapper):
    """Keeps each step's info as the loop reads it; drops the aligned error at ``drop_at``."""

    def __init__(self, env, drop_at=None):
        super().__init__(env)
        self.infos, self.rewards, self.drop_at = [], [], drop_at

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        if len(self.infos) == self.drop_at:
            info = {k: v for k, v in info.items() if k != "error_aligned_mm"}
        self.infos.append(info)
        self.rewards.append(float(reward))
        return obs, reward, terminated, truncated, info


def _short_arm_env():
    return gym.make("humotion_gym/ArmTrack-v2", terminate_on_lost=False, episode_frames=6,
                    width=64, height=64)  # fmt: skip


def test_an_episodes_numbers_are_its_frames_scores():
    """Every frame's error in order, their mean, the last frame's: read from the steps' infos."""
    env = _Scores(_short_arm_env())
    result = run_episode(RandomPolicy(env.action_space), env, seed=3)
    errors = [float(i["error_mm"]) for i in env.infos]
    aligned = [float(i["error_aligned_mm"]) for i in env.infos]
    assert len(errors) == 6 and result.errors_mm == errors
    assert result.mean_error_mm == float(np.mean(errors))
    assert result.final_error_mm == errors[-1] != errors[0]
    assert result.aligned_errors_mm == aligned
    assert result.mean_aligned_error_mm == float(np.mean(aligned))
    assert result.mean_reward == float(np.mean(env.rewards))
    # a frame without the aligned error: none for the whole episode, not a shorter series
    gap = _Scores(_short_arm_env(), drop_at=3)
    partial = run_episode(RandomPolicy(gap.action_space), gap, seed=3)
    assert partial.aligned_errors_mm is None and partial.mean_aligned_error_mm is None
    assert partial.errors_mm == errors  # the same seeds: the same episode
    # evaluate runs the seeds seed, seed + 1, ... each as run_episode alone
    plain = _short_arm_env()
    runs = evaluate(make("hold", plain), plain, 3, seed=2)
    assert [r.seed for r in runs] == [2, 3, 4]
    assert runs[1].errors_mm == run_episode(make("hold", plain), plain, seed=3).errors_mm


def test_the_first_call_is_made_before_the_episodes_and_left_out_of_their_timing(monkeypatch):
    # a fake clock: the agent's first call costs 100 s (numba compiling), every other 1 ms
    clock = [0.0]
    monkeypatch.setattr(evaluation, "time", type("Clock", (), {"perf_counter": lambda: clock[0]}))

    class FirstCallCostly:
        def __init__(self, space):
            self.space, self.calls = space, 0

        def predict(self, obs, state=None, episode_start=None, deterministic=True):
            clock[0] += 100.0 if self.calls == 0 else 0.001
            self.calls += 1
            return np.zeros(self.space.shape, self.space.dtype), None

    env = gym.make("humotion_gym/ArmTrack-v2", terminate_on_lost=False)
    agent = FirstCallCostly(env.action_space)
    assert warm_up(agent, env, seed=0) == pytest.approx(100.001)  # two frames
    timed = [r.ms_per_frame for r in evaluate(agent, env, 2, seed=0)]
    assert timed == pytest.approx([1.0, 1.0])
    # the check can fail: without the warm-up the first episode carries the 100 s
    cold = evaluate(FirstCallCostly(env.action_space), env, 1, seed=0)[0]
    assert cold.ms_per_frame > 1000.0


def test_after_the_warm_up_an_episode_calls_no_kernel_it_did_not(monkeypatch):
    """The main command's agent and task: no kernel compiles inside an episode.

    On a first run numba compiles a kernel, for each signature, at its first
    call; one first called mid-episode (the coverage term's, before its
    points appeared some frames in) charges its seconds to that episode's
    ms/frame. Every compiled kernel Python calls is recorded with its
    argument types (what numba dispatches on): those an episode calls must
    all have been called before it, in the agent's making and the warm-up.
    """
    import numba
    from numba.core.registry import CPUDispatcher

    from baselines.filtering import _compiled as filtering_kernels
    from baselines.filtering import weights
    from baselines.observation import _compiled as observation_kernels
    from baselines.priors import _tree_compiled as tree_kernels
    from humotion_gym import _compiled as body_kernels

    calls: dict[str, set] = {"before": set(), "episode": set()}
    phase = ["before"]

    def recording(name, kernel):
        def call(*args):
            calls[phase[0]].add((name, tuple(str(numba.typeof(a)) for a in args)))
            return kernel(*args)

        return call

    for module in (body_kernels, observation_kernels, tree_kernels, filtering_kernels):
        for name, kernel in list(vars(module).items()):
            # the kernels Python calls (pose_block is called from compiled code alone)
            if isinstance(kernel, CPUDispatcher) and not name.startswith("_"):
                if name != "pose_block":
                    monkeypatch.setattr(module, name, recording(name, kernel))
    wrapped = recording("wrapped_offsets", filtering_kernels.wrapped_offsets)
    monkeypatch.setattr(weights, "wrapped_offsets", wrapped)
    env = gym.make("humotion_gym/BodyTrack-v2", terminate_on_lost=False)
    agent = make("pf-tree", env, n_particles=50, seed=0)
    warm_up(agent, env, seed=0)
    phase[0] = "episode"
    run_episode(agent, env, seed=0)
    names = {name for name, _ in calls["episode"]}
    assert {"cone_bases", "point_costs", "coverage_sums", "descend", "replay"} <= names
    assert calls["episode"] <= calls["before"], sorted(calls["episode"] - calls["before"])


def test_cli_track_and_render(tmp_path, capsys):
    assert (
        main(
            [
                "track",
                "--task",
                "ArmTrack-v2",
                "--agent",
                "pf-cv",
                "--particles",
                "50",
                "--episodes",
                "2",
                "--json",
            ]
        )
        == 0
    )
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert out["summary"]["episodes"] == 2 and len(out["episodes"][0]["errors_mm"]) == 30
    assert out["warm_up_s"] >= 0.0
    video = tmp_path / "clip.mp4"
    assert main(["render", "--task", "BodyTrack-v2", "--frames", "12", "--out", str(video)]) == 0
    assert video.stat().st_size > 0 and video.with_suffix(".png").is_file()


@pytest.mark.parametrize("prior", ["tree", "pca", "slds"])
def test_cli_synth_writes_a_bvh_the_parser_reads_back(tmp_path, prior):
    from humotion_gym.mocap.export import read_motion_bvh

    out = tmp_path / f"{prior}.bvh"
    assert main(["synth", "--prior", prior, "--seconds", "0.5", "--out", str(out)]) == 0
    params, fps = read_motion_bvh(out)
    assert fps == 30.0 and params.shape[0] >= 15 and np.all(np.isfinite(params))


#: Fit settings that keep a prior's fit short where making the agent is what is checked:
#: the SLDS's EM (10 iterations per activity model, about 4 s on the two tasks) is
#: checked by tests/priors/test_slds.py.
QUICK_FITS = {"pf-slds": {"n_iter": 1}}


def test_every_agent_is_made_or_refuses_with_a_reason():
    for name in AGENTS:
        for task in ("ArmTrack-v2", "SideWalk-v2"):
            env = gym.make(f"humotion_gym/{task}")
            try:
                agent = make(name, env, n_particles=20, fit_settings=QUICK_FITS.get(name))
            except TaskNotSupported as exc:
                assert "walking" in str(exc) or "supports" in str(exc)
                continue
            except ModuleNotFoundError as exc:  # a detector agent without the rl extra
                if importlib.util.find_spec("torch") is not None:
                    raise
                assert exc.name == "torch" and name in str(exc), exc
                continue
            obs, info = env.reset(seed=0)
            action, _ = agent.predict(obs, episode_start=np.array([True]))
            assert env.action_space.contains(action)


@pytest.mark.parametrize("views", [1, 2])
def test_the_backdrop_is_read_at_each_episodes_first_frame_only(views):
    env = gym.make("humotion_gym/BodyTrack-v2", terminate_on_lost=False, views=views)
    agent = make("pf-cv", env, n_particles=50, seed=0)
    assert agent.observation_model.backdrop
    for seed in (0, 1):
        obs, info = env.reset(seed=seed)
        agent.predict(obs, episode_start=np.array([True]))
        first = [seen.backdrop for seen in agent.likelihood.first]
        assert len(first) == views and all(b is not None for b in first)
        seen = read_observation(obs)
        for view, (frame, camera) in enumerate(zip(seen.frames, seen.cameras, strict=True)):
            # each view's backdrop from its own frame and camera
            expected = agent.observation_model.read_backdrop(
                frame, seen.initial_pose, seen.shape, camera
            )
            np.testing.assert_array_equal(first[view].image, expected.image)
            np.testing.assert_array_equal(first[view].known, expected.known)
        for _ in range(3):  # later frames leave it as it was
            obs, _, _, _, info = env.step(agent.predict(obs)[0])
        agent.predict(obs)
        assert all(a.backdrop is b for a, b in zip(agent.likelihood.first, first, strict=True))


def test_pf_follow_moves_the_body_and_holds_the_first_articulation():
    env = gym.make("humotion_gym/BodyTrack-v2", terminate_on_lost=False)
    base = env.unwrapped
    agent = make("pf-follow", env, n_particles=100, seed=0)
    obs, info = env.reset(seed=2)
    first = np.asarray(obs["initial_pose"])
    estimates = []
    start = np.array([True])
    for _ in range(6):
        action, _ = agent.predict(obs, episode_start=start)
        start = np.array([False])
        estimates.append(base.action_to_pose(action, first))
        obs, _, _, _, info = env.step(action)
    estimates = np.array(estimates)
    # float32 actions: the articulation within their rounding of the first pose's
    np.testing.assert_allclose(estimates[:, 6:], np.broadcast_to(first[6:], (6, 19)), atol=1e-3)
    assert np.ptp(estimates[:, :3], axis=0).max() > 1.0  # the root moves
    with pytest.raises(ValueError, match="supports"):
        make("pf-follow", gym.make("humotion_gym/ArmTrack-v2"), n_particles=10)


def test_the_annealed_filters_settings_come_from_the_spec_the_task_and_the_caller(monkeypatch):
    import dataclasses

    from baselines import agents
    from baselines.filtering import AnnealedParticleFilter, ParticleFilter

    env = gym.make("humotion_gym/ArmTrack-v2")
    # SideWalk's apf-cv keeps the paper's settings (none chosen for it there)
    default = make("apf-cv", gym.make("humotion_gym/SideWalk-v2"), n_particles=10)
    assert isinstance(default.filter, AnnealedParticleFilter)
    assert (default.filter.layers, default.filter.alpha) == (10, 0.5)
    assert (default.filter.diffusion, default.filter.beta_max) == (1.0, np.inf)
    registered = make("apf-cv", env, n_particles=10)
    chosen_in_file = load_settings()["apf-cv"].task_filter["ArmTrack-v2"]
    assert (registered.filter.alpha, registered.filter.diffusion) == (
        chosen_in_file["alpha"],
        chosen_in_file["diffusion"],
    )
    # A task's own settings override the spec's; the caller's override both.
    spec = dataclasses.replace(
        AGENTS["apf-cv"], task_filter_settings={"ArmTrack-v2": {"alpha": 0.7, "diffusion": 0.3}}
    )
    monkeypatch.setitem(agents.AGENTS, "apf-test", spec)
    chosen = make("apf-test", env, n_particles=10)
    assert (chosen.filter.alpha, chosen.filter.diffusion, chosen.filter.layers) == (0.7, 0.3, 10)
    called = make("apf-test", env, n_particles=10, filter_settings={"layers": 3.0, "beta_max": 1})
    assert (called.filter.layers, called.filter.beta_max, called.filter.alpha) == (3, 1.0, 0.7)
    body = make("apf-test", gym.make("humotion_gym/BodyTrack-v2"), n_particles=10)
    assert (body.filter.alpha, body.filter.diffusion) == (0.5, 1.0)  # ArmTrack's alone
    one = make("apf-test", env, n_particles=10, filter_settings={"layers": 1})
    assert type(one.filter) is ParticleFilter
    with pytest.raises(ValueError, match="not the filter's"):
        make("apf-cv", env, n_particles=10, filter_settings={"sharpness": 2.0})
    with pytest.raises(ValueError, match="plain particle filter"):
        make("pf-cv", env, n_particles=10, filter_settings={"alpha": 0.7})
    with pytest.raises(ValueError, match="alpha must be in"):
        make("apf-cv", env, n_particles=10, filter_settings={"alpha": 1.5})


@pytest.mark.parametrize(
    ("agent", "setting", "reads"),
    [
        ("spf-cv", "alpha", "search_top"),
        ("spf-cv", "diffusion", "search_top"),
        ("spf-cv", "beta_max", "search_top"),
        ("spf-cv", "layers", "search_top"),
        ("ppf-cv", "alpha", r"\['diffusion'\]"),
        ("ppf-cv", "beta_max", r"\['diffusion'\]"),
        ("ppf-cv", "layers", r"\['diffusion'\]"),
    ],
)
def test_a_filter_setting_the_agents_filter_does_not_read_is_refused(
    monkeypatch, agent, setting, reads
):
    """A local search reads none of the annealed filter's settings, partitioned sampling
    the diffusion alone: one of the others would run the agent as it is, silently."""
    import dataclasses

    from baselines import agents

    spec = dataclasses.replace(AGENTS["pf-cv"], partitioned=True)
    monkeypatch.setitem(agents.AGENTS, "ppf-cv", spec)
    env = gym.make("humotion_gym/ArmTrack-v2")
    with pytest.raises(
        ValueError, match=rf"\['{setting}'\] are not read by {agent}'s filter.*{reads}"
    ):
        make(agent, env, n_particles=3, filter_settings={setting: 2})
    # an annealed agent at one layer is the plain filter: its survival rate unread
    with pytest.raises(ValueError, match=r"\['alpha'\] are not read with layers 1: apf-cv"):
        make("apf-cv", env, n_particles=3, filter_settings={"layers": 1, "alpha": 0.7})
    # what each filter reads is taken
    assert spec.filter_settings_for("ArmTrack-v2", {"diffusion": 0.3})["diffusion"] == 0.3
    assert AGENTS["spf-cv"].filter_settings_for("", {"search_top": 2})["search"].top == 2


def test_the_filter_agent_refuses_counts_and_seeds_it_would_have_cut():
    """``n_particles=2.7`` ran 2 particles and ``layers=2.5`` a 2-layer annealed
    filter; a seed of 1.7 or -1 failed inside numpy."""
    from baselines.agents import ParticleFilterAgent
    from baselines.priors import constant_velocity

    env = gym.make("humotion_gym/ArmTrack-v2")
    build = {"task": env, "prior": constant_velocity, "fitted": None}
    for name, value, least in [
        ("n_particles", 2.7, 1), ("n_particles", 0, 1), ("n_particles", "30", 1),
        ("layers", 2.5, 1), ("layers", 0, 1), ("seed", 1.7, 0), ("seed", -1, 0),
    ]:  # fmt: skip
        with pytest.raises(
            ValueError,
            match=rf"^ParticleFilterAgent: {name}: expected an integer >= {least}, got ",
        ):
            ParticleFilterAgent(**{"n_particles": 3, **build, name: value})
    agent = ParticleFilterAgent(**build, n_particles=np.int64(3), layers=np.int64(2), seed=5)
    assert agent.filter.n == 3 and agent.filter.layers == 2 and agent.seed == 5


def test_the_filter_agent_refuses_a_setting_its_filter_does_not_read():
    from baselines.agents import ParticleFilterAgent
    from baselines.filtering.search import LocalSearch
    from baselines.priors import constant_velocity

    env = gym.make("humotion_gym/ArmTrack-v2")
    build = {"task": env, "prior": constant_velocity, "fitted": None, "n_particles": 3}
    with pytest.raises(ValueError, match=r"\['alpha'\] are not read by its filter, a particle"):
        ParticleFilterAgent(**build, search=LocalSearch(), alpha=0.3)
    with pytest.raises(ValueError, match=r"\['beta_max'\] are not read by its filter, a partit"):
        ParticleFilterAgent(**build, partitioned=True, diffusion=0.3, beta_max=1.0)
    with pytest.raises(ValueError, match=r"\['diffusion'\] are not read by its filter, a plain"):
        ParticleFilterAgent(**build, diffusion=0.3)


def test_the_filters_estimate_is_answered_as_its_action_in_the_episodes_range():
    """The estimate mapped by the task's map with the episode's initial root (BodyTrack's
    root is free: its range is the initial root +- root_range_mm)."""
    env = gym.make("humotion_gym/BodyTrack-v2", terminate_on_lost=False)
    agent = make("pf-cv", env, n_particles=10, seed=0)
    obs, _ = env.reset(seed=1)
    initial = np.asarray(obs["initial_pose"])
    estimate = initial + np.linspace(-0.2, 0.3, 25)
    estimate[:3] = initial[:3] + (300.0, -700.0, 50.0)
    agent.filter.step = lambda features: estimate.copy()
    action, _ = agent.predict(obs, episode_start=np.array([True]))
    np.testing.assert_array_equal(action, pose_to_action(env.unwrapped.task, estimate, initial))
    np.testing.assert_allclose(action[:3], [300 / 2500, -700 / 2500, 50 / 2500], atol=1e-6)


def test_a_filters_episode_is_its_seed_and_episode_seed_alone():
    env = gym.make("humotion_gym/ArmTrack-v2", terminate_on_lost=False)
    obs, _ = env.reset(seed=0)
    agent = make("pf-cv", env, n_particles=20, seed=3)
    answers = []
    for episode_seed in (1, 2, 1):
        agent.seed_episode(episode_seed)
        answers.append(agent.predict(obs, episode_start=np.array([True]))[0])
    assert np.array_equal(answers[0], answers[2])
    assert not np.array_equal(answers[0], answers[1])
    other = make("pf-cv", env, n_particles=20, seed=4)
    other.seed_episode(1)
    assert not np.array_equal(other.predict(obs, episode_start=np.array([True]))[0], answers[0])


def test_an_episode_begins_at_episode_start_or_where_the_initial_pose_changes():
    pose = np.zeros(25)
    moved = pose.copy()
    moved[5] = 0.1
    assert episode_begins(None, pose, None)  # before the first episode
    assert not episode_begins(None, pose, pose.copy())
    assert episode_begins(None, moved, pose)
    assert episode_begins(np.array([True]), pose, pose.copy())
    assert not episode_begins(np.array([False]), pose, pose.copy())
    assert episode_begins(np.array([False]), moved, pose)


def test_a_version_1_task_is_not_described_to_an_agent():
    with pytest.warns(FutureWarning):
        env = gym.make("humotion_gym/ArmTrack-v1")
    with pytest.raises(TaskNotSupported, match="ArmTrack-v2"):
        describe(env)
    assert describe(gym.make("humotion_gym/ArmTrack-v2")).name == "ArmTrack-v2"


def test_each_body_parts_stage_places_that_parts_cones():
    stages = body_part_stages(np.arange(25))
    placed = {stage.name: {CONE_NAMES[c] for c in stage.group} for stage in stages}
    assert placed == {
        "torso": {"torso", "head"},
        "right_arm": {"r_upper_arm", "r_forearm"},
        "left_arm": {"l_upper_arm", "l_forearm"},
        "right_leg": {"r_thigh", "r_shin"},
        "left_leg": {"l_thigh", "l_shin"},
    }


@pytest.mark.parametrize("name", ["pf-cv", "pf-mix"])  # one prior module, and a mixture's two
def test_an_agent_pickles_and_deep_copies_to_the_same_tracker(name):
    """A tracker holds its prior's module: pickled by name, so a copy tracks the same."""
    import copy
    import pickle

    env = gym.make("humotion_gym/BodyTrack-v2")
    agent = make(name, env, n_particles=20, seed=0)
    obs, _ = env.reset(seed=1)
    action, _ = agent.predict(obs, episode_start=True)
    copies = [copy.deepcopy(agent), pickle.loads(pickle.dumps(agent))]
    obs, *_ = env.step(action)
    want = agent.predict(obs, episode_start=False)[0]
    for other in copies:
        assert np.array_equal(other.predict(obs, episode_start=False)[0], want)
    with pytest.raises(TypeError, match=r"cannot pickle 'module' object \(json\)"):
        pickle.dumps(json)  # a module that is no prior is refused as before


def test_an_agent_refusing_a_task_is_named_as_the_user_named_it():
    """pf-pca on ArmTrack-v2: the agent's name and the prior's reason, not ``cyclic_pca``."""
    env = gym.make("humotion_gym/ArmTrack-v2")
    with pytest.raises(TaskNotSupported) as caught:
        make("pf-pca", env, n_particles=5)
    message = str(caught.value)
    assert message.startswith("pf-pca cannot track 'ArmTrack-v2': the cyclic PCA model covers")
    assert "cyclic_pca" not in message


class WithoutPartial:
    """A likelihood with the three calls every filter makes, not log_likelihood_partial."""

    def __init__(self, model):
        self.model = model

    def prepare(self, frame, given=None):
        return self.model.prepare(frame, given)

    def read_first_frame(self, *args):
        return self.model.read_first_frame(*args)

    def log_likelihood(self, *args):
        return self.model.log_likelihood(*args)


def test_a_partitioned_agent_refuses_a_likelihood_without_its_stages_call(monkeypatch):
    """It was accepted and the filter raised AttributeError on its first frame."""
    from baselines.agents import AgentSpec
    from baselines.observation import task_model

    spec = AgentSpec("baselines.priors.constant_velocity", AGENTS["pf-cv"].fit_settings,
                     partitioned=True)  # fmt: skip
    monkeypatch.setitem(AGENTS, "ppf-cv", spec)
    env = gym.make("humotion_gym/BodyTrack-v2", terminate_on_lost=False)
    model = WithoutPartial(task_model(describe(env).task))
    with pytest.raises(TypeError, match=r"^agents.make: observation_model must have .*"
                       r"log_likelihood_partial for ppf-cv .*WithoutPartial lacks "
                       r"log_likelihood_partial$"):  # fmt: skip
        make("ppf-cv", env, n_particles=20, observation_model=model)
    # the plain filter calls the three alone
    assert make("pf-cv", env, n_particles=20, observation_model=model).likelihood.model is model


def test_a_detector_agent_refuses_a_likelihood_that_would_drop_its_term():
    """pf-cv-det with observation_model=task_model(...) silently scored without the detector."""
    from baselines.observation import task_model

    env = gym.make("humotion_gym/ArmTrack-v2", terminate_on_lost=False)
    model = task_model(describe(env).task)
    for name in ("pf-cv-det", "spf-cv-det"):
        with pytest.raises(ValueError, match=rf"^agents.make: observation_model: {name} builds "
                           r"its own likelihood.*detector's term.*\(as .*cv, its prior"):  # fmt: skip
            make(name, env, n_particles=20, observation_model=model)
