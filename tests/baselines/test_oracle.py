"""Truth oracles and the error split (``baselines.diagnostics``, ``humotion-gym oracle``)."""

import gzip
import itertools
import json

import gymnasium as gym
import numpy as np
import pytest

import humotion_gym  # noqa: F401
from baselines.agents import (
    ParticleFilterAgent,
    agent_names,
    make,
    register_reference,
    tracking_env,
)
from baselines.cli import main
from baselines.diagnostics.oracle import (
    OracleFeed,
    OracleObservation,
    OracleSettings,
    TruthOracle,
    left_right_partners,
    with_oracle,
)
from baselines.diagnostics.split import markdown_report, parse_oracle, run_split, split_table
from baselines.leaderboard.evaluation import run_episode
from baselines.observation.keypoints import KeypointScorer
from humotion_gym.body import CONE_KEYPOINTS, KEYPOINT_NAMES, forward_kinematics

SCORED = np.arange(15)


@pytest.fixture(scope="module")
def env():
    e = gym.make("humotion_gym/BodyTrack-v2", split="test", terminate_on_lost=False)
    e.reset(seed=4)
    yield e
    e.close()


def _poses(env, n=12, spread=0.1, seed=0):
    base = tracking_env(env)
    rng = np.random.default_rng(seed)
    truth = base.true_pose()
    poses = truth + rng.normal(0.0, spread, (n, 25)) * np.r_[np.full(3, 300.0), np.ones(22)]
    return truth, np.vstack([truth, poses])


def _slow(oracle, obs, poses, shape, camera, placed=None):
    """The definition, one pose and one keypoint (or left/right pair) at a time."""
    names = [KEYPOINT_NAMES[k] for k in oracle.keypoints]
    placed = set(range(len(names))) if placed is None else placed
    units = [[i] for i in range(len(names))]  # labelled: each keypoint alone
    if oracle.settings.kind == "2d-unlabelled":
        units = [[i] for i, n in enumerate(names) if n[:2] not in ("r_", "l_")]
        units += [[i, names.index("l_" + n[2:])] for i, n in enumerate(names) if n[:2] == "r_"]
    out = []
    for pose in poses:
        kp = forward_kinematics(pose, shape)
        pts = [camera.project(kp[k]) if oracle.dims == 2 else kp[k] for k in oracle.keypoints]
        cost = 0.0
        for unit in units:
            other = {unit[0]: unit[-1], unit[-1]: unit[0]}
            members = [k for k in unit if k in placed]
            if members:
                straight = sum(float(np.sum((pts[k] - obs.points[k]) ** 2)) for k in members)
                swapped = sum(float(np.sum((pts[k] - obs.points[other[k]]) ** 2)) for k in members)
                cost += min(straight, swapped)
        out.append(-cost / (2 * obs.sigma**2))
    return np.array(out)


@pytest.mark.parametrize(
    "settings",
    [
        OracleSettings("2d"),
        OracleSettings("2d-unlabelled"),
        OracleSettings("3d"),
        OracleSettings("3d", noise_mm=10.0),
    ],  # fmt: skip
    ids=lambda s: s.label,
)
def test_log_likelihood_matches_the_slow_definition(env, settings):
    base = tracking_env(env)
    oracle = TruthOracle(settings, SCORED, seed=3)
    oracle.start_episode(4)
    obs = oracle.show(base.true_pose(), base.shape, base.camera)
    _, poses = _poses(env)
    fast = oracle.log_likelihood(oracle.prepare(None), poses, base.shape, base.camera)
    np.testing.assert_allclose(fast, _slow(oracle, obs, poses, base.shape, base.camera), rtol=1e-9)
    # partial figures: the torso, then the right arm, then the left leg
    groups = [[0, 1], [2, 3], [8, 9]]
    part = oracle.log_likelihood_partial(obs, poses, base.shape, base.camera, groups)
    assert part.shape == (poses.shape[0], 4)
    np.testing.assert_allclose(part[:, -1], fast, rtol=1e-12)
    placed: set[int] = set()
    for g, group in enumerate(groups):
        placed |= {int(k) for c in group for k in CONE_KEYPOINTS[c]}
        slow = _slow(oracle, obs, poses, base.shape, base.camera, placed)
        np.testing.assert_allclose(part[:, g], slow, rtol=1e-9)


@pytest.mark.parametrize("unlabelled", [False, True])
def test_weighted_capped_keypoint_costs_match_the_definition(unlabelled):
    # Each keypoint's term is its own weight times its squared distance, then
    # capped; an unlabelled pair takes the cheaper assignment of its placed
    # members; a point that cannot be placed (NaN) costs inf.
    rng = np.random.default_rng(21)
    scorer = KeypointScorer(SCORED, unlabelled, "Test")
    points = rng.normal(0.0, 2.0, (6, 15, 2))
    points[5, 4] = np.nan
    observed = rng.normal(0.0, 2.0, (15, 2))
    weights = rng.uniform(0.1, 2.0, 15)
    cap = 3.0
    masks = scorer.partial_masks([[0, 1], [2, 3], [8, 9]])
    got = scorer.cost(points, observed, masks, weights, cap)
    names = [KEYPOINT_NAMES[k] for k in SCORED]
    partner = [
        names.index({"r_": "l_", "l_": "r_"}[n[:2]] + n[2:]) if unlabelled and n[:2] in ("r_", "l_")
        else i
        for i, n in enumerate(names)
    ]  # fmt: skip
    units = [[i] if partner[i] == i else [i, partner[i]] for i in range(15) if i <= partner[i]]
    for n in range(points.shape[0]):
        for m, mask in enumerate(masks):
            want = 0.0
            for unit in units:
                members = [k for k in unit if mask[k]]
                straight = sum(
                    min(weights[k] * float(np.sum((points[n, k] - observed[k]) ** 2)), cap)
                    for k in members
                )
                swapped = sum(
                    min(weights[k] * float(np.sum((points[n, k] - observed[partner[k]]) ** 2)), cap)
                    for k in members
                )
                want += min(straight, swapped)
            if n == 5 and mask[4]:
                assert got[n, m] == np.inf
            else:
                assert got[n, m] == pytest.approx(want, rel=1e-12), (n, m)
    assert np.all(got[:5, -1] < 15 * cap) and np.any(got[:5, -1] > 3 * cap)


def test_the_truth_scores_highest_without_noise(env):
    base = tracking_env(env)
    truth, poses = _poses(env, n=40, spread=0.02)
    kp = forward_kinematics(truth, base.shape)
    for kind in ("2d", "2d-unlabelled", "3d"):
        oracle = TruthOracle(OracleSettings(kind), SCORED)
        points = kp if kind == "3d" else base.camera.project(kp)
        scores = oracle.log_likelihood(OracleObservation(points, 1.0), poses, base.shape,
                                       base.camera)  # fmt: skip
        assert scores[0] == pytest.approx(0.0, abs=1e-9) and np.all(scores[1:] < scores[0])
    bad = poses[:2].copy()
    bad[1, 5] = np.nan
    oracle = TruthOracle(OracleSettings("2d"), SCORED)
    out = oracle.log_likelihood(OracleObservation(base.camera.project(kp), 1.0), bad,
                                base.shape, base.camera)  # fmt: skip
    assert np.isfinite(out[0]) and out[1] == -np.inf


def test_noise_is_the_seeds_alone(env):
    base = tracking_env(env)

    def shown(seed, episode):
        oracle = TruthOracle(OracleSettings("3d"), SCORED, seed=seed)
        oracle.start_episode(episode)
        return [oracle.show(base.true_pose(), base.shape, base.camera).points for _ in range(3)]

    a, b = shown(0, 7), shown(0, 7)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)
    assert not np.array_equal(a[1], a[0])  # a fresh draw every frame
    assert not np.array_equal(shown(0, 8)[0], a[0]) and not np.array_equal(shown(1, 7)[0], a[0])
    # 1 px at the body's depth, in mm
    oracle = TruthOracle(OracleSettings("3d", noise_px=2.0), SCORED)
    sigma = oracle.show(base.true_pose(), base.shape, base.camera).sigma
    pelvis = forward_kinematics(base.true_pose(), base.shape)[0]
    assert sigma == pytest.approx(2.0 * base.camera.depth(pelvis) / base.camera.focal)


def test_unlabelled_scores_the_left_right_swapped_truth_as_the_truth(env):
    base = tracking_env(env)
    truth, _ = _poses(env)
    points = base.camera.project(forward_kinematics(truth, base.shape))
    swap = left_right_partners(range(15))
    assert [KEYPOINT_NAMES[i] for i in swap[[2, 10]]] == ["l_knee", "l_elbow"]
    poses = truth[None]
    for kind, same in (("2d-unlabelled", True), ("2d", False)):
        oracle = TruthOracle(OracleSettings(kind), SCORED)
        straight = oracle.log_likelihood(OracleObservation(points, 3.0), poses, base.shape,
                                         base.camera)  # fmt: skip
        swapped = oracle.log_likelihood(OracleObservation(points[swap], 3.0), poses, base.shape,
                                        base.camera)  # fmt: skip
        # the labelled oracle is the mutation: the same check fails on it
        assert bool(swapped[0] == pytest.approx(straight[0], abs=1e-9)) is same
    # one pair swapped alone, too: pair by pair, not limb by limb
    one = np.arange(15)
    one[[3, 6]] = [6, 3]  # the ankles only
    oracle = TruthOracle(OracleSettings("2d-unlabelled"), SCORED)
    assert oracle.log_likelihood(OracleObservation(points[one], 3.0), poses, base.shape,
                                 base.camera)[0] == pytest.approx(0.0, abs=1e-9)  # fmt: skip


def test_oracles_are_never_agents(env):
    oracle = TruthOracle(OracleSettings("2d"), SCORED)
    assert not hasattr(oracle, "predict")
    assert not any(name in agent_names() for name in ("2d", "2d-unlabelled", "3d", "oracle"))
    with pytest.raises(ValueError, match="reads the truth"):
        register_reference("oracle-2d", TruthOracle)
    assert "oracle-2d" not in agent_names()
    with pytest.raises(ValueError, match="observation_model: TruthOracle reads the truth"):
        make("pf-cv", env, n_particles=5, observation_model=oracle)
    with pytest.raises(TypeError, match="no likelihood to replace"):
        with_oracle(make("hold", env), oracle)
    # the leaderboard takes registered names only
    assert main(["leaderboard", "--agents", "2d", "--episodes", "1"]) == 2


def test_the_feed_shows_the_frame_on_show_and_the_agent_tracks_with_it(env):
    oracle = TruthOracle(OracleSettings("2d", noise_px=1e-6), SCORED)
    feed = OracleFeed(env, oracle)
    base = tracking_env(env)
    agent = with_oracle(make("pf-cv", env, n_particles=30, seed=1), oracle)
    assert isinstance(agent, ParticleFilterAgent)
    seen = []

    class Watch:
        def predict(self, obs, state=None, episode_start=None, deterministic=True):
            truth = base.camera.project(forward_kinematics(base.true_pose(), base.shape))
            seen.append(float(np.abs(oracle.prepare(None).points - truth).max()))
            return agent.predict(obs, state, episode_start, deterministic)

    result = run_episode(Watch(), feed, seed=2)
    assert len(seen) == len(result.errors_mm) and max(seen) < 1e-4
    with pytest.raises(ValueError, match="seed"):
        feed.reset()


def test_run_split_end_to_end_on_the_synthetic_data():
    kwargs = {"episode_frames": 3}
    oracles = [None, parse_oracle("2d"), parse_oracle("2d-unlabelled"), parse_oracle("3d:10mm")]
    out = run_split("BodyTrack-v2", ["pf-cv"], oracles, particles=10, episodes=2,
                    declared=False, seed=5, env_kwargs=kwargs, progress=False)  # fmt: skip
    rows = {(r["agent"], r["likelihood"]): r for r in out["rows"]}
    assert list(rows) == [("hold", "none"), ("pf-cv", "image"), ("pf-cv", "2d 1px"),
                          ("pf-cv", "2d-unlabelled 3px"), ("pf-cv", "3d 10mm")]  # fmt: skip
    assert rows[("hold", "none")]["ess"] is None and rows[("pf-cv", "2d 1px")]["ess"] >= 1.0
    # the image row is the leaderboard's loop with the same agent and seeds
    env = gym.make("humotion_gym/BodyTrack-v2", split="test", terminate_on_lost=False, **kwargs)
    agent = make("pf-cv", env, n_particles=10, seed=5)
    loop = [run_episode(agent, env, s).mean_error_mm for s in (5, 6)]
    assert rows[("pf-cv", "image")]["error_mm"] == pytest.approx(np.mean(loop), rel=1e-12)
    hold = rows[("hold", "none")]["error_mm"]
    assert rows[("pf-cv", "3d 10mm")]["x_hold"] == pytest.approx(
        hold / rows[("pf-cv", "3d 10mm")]["error_mm"]
    )
    text = markdown_report([out])
    assert "| pf-cv | 2d 1px |" in text and "search: 3d 10mm mm" in text
    # every table's rows have its header's columns, with or without 3D oracles
    without = {**out, "rows": [r for r in out["rows"] if r["likelihood"] != "3d 10mm"]}
    for report in (text, markdown_report([without])):
        for block in report.split("\n\n"):
            widths = {line.count("|") for line in block.splitlines() if line.startswith("|")}
            assert len(widths) <= 1, block
    # again: the same numbers
    again = run_split("BodyTrack-v2", ["pf-cv"], oracles[2:3], particles=10, episodes=2,
                      declared=False, seed=5, env_kwargs=kwargs, progress=False)  # fmt: skip
    assert again["rows"][1]["episodes"] == rows[("pf-cv", "2d-unlabelled 3px")]["episodes"]


def test_cli_oracle_writes_results_and_table(tmp_path, capsys):
    code = main(["oracle", "--agents", "pf-cv", "--particles", "5", "--declared",
                 "--episodes", "1", "--oracles", "image", "3d", "--out", str(tmp_path)])  # fmt: skip
    assert code == 0
    text = (tmp_path / "table.md").read_text()
    assert "the first 1 of 36 declared test windows" in text and "| pf-cv | 3d 1px@depth |" in text
    data = json.loads(gzip.decompress((tmp_path / "results.json.gz").read_bytes()))
    assert [r["likelihood"] for r in data["results"][0]["rows"]] == ["none", "image",
                                                                     "3d 1px@depth"]  # fmt: skip
    assert "wrote" in capsys.readouterr().out


@pytest.mark.parametrize(
    "argv",
    [
        ["--oracles", "4d"],
        ["--oracles", "2d:-1"],
        ["--oracles", "2d", "2d:1"],
        ["--oracles", "2d:3mm"],
        ["--agents", "random"],
        ["--noise-mm", "0"],
        ["--declared", "--split", "validation"],
        ["--episodes", "0"],
        ["--set", "steps=3"],
        ["--set", "fit.steps"],
        ["--set", "fit.nonsense=1"],
        ["--agents", "pf-cv", "--set", "filter.search_steps=3"],
        ["--agents", "hold", "--set", "fit.damping=0.3"],
    ],
    ids=lambda a: " ".join(a),
)
def test_cli_oracle_bad_arguments_are_one_line_exit_2(argv, capsys):
    assert main(["oracle", "--particles", "5", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "error" in err


def test_a_setting_reaches_every_agent_and_the_record(tmp_path):
    """``--set filter.search_steps=0``: the climb takes no step, so spf-cv is pf-cv."""
    common = ["oracle", "--particles", "5", "--episodes", "1", "--oracles", "3d", "--seed", "3"]
    assert main([*common, "--agents", "pf-cv", "--out", str(tmp_path / "cv")]) == 0
    argv = [*common, "--agents", "spf-cv", "--set", "filter.search_steps=0"]
    assert main([*argv, "--out", str(tmp_path / "spf")]) == 0
    assert main([*common, "--agents", "spf-cv", "--out", str(tmp_path / "climb")]) == 0

    def read(name):
        data = json.loads(gzip.decompress((tmp_path / name / "results.json.gz").read_bytes()))
        return data["settings"], data["results"][0]["rows"][1]["error_mm"]

    settings, no_steps = read("spf")
    assert settings["set"] == {"filter.search_steps": 0}
    assert no_steps == read("cv")[1] != read("climb")[1]
    assert "set" not in read("cv")[0]


def test_settings_refuse_what_they_cannot_be():
    with pytest.raises(ValueError, match="kind"):
        OracleSettings("depth")
    with pytest.raises(ValueError, match="noise_px"):
        OracleSettings("2d", noise_px=0.0)
    # noise so small its variance underflows: every pose -inf, uniform weights, no oracle
    with pytest.raises(ValueError, match=r"noise_px: expected a number in \[1e-09, 1000\]"):
        OracleSettings("2d", noise_px=1e-200)
    with pytest.raises(ValueError, match="noise_mm"):
        OracleSettings("3d", noise_mm=1e-320)
    OracleSettings("3d", noise_mm=1e-9)  # the least taken
    with pytest.raises(ValueError, match="noise_mm"):
        OracleSettings("2d", noise_mm=10.0)
    with pytest.raises(ValueError, match="keypoints"):
        TruthOracle(OracleSettings("2d"), [])
    oracle = TruthOracle(OracleSettings("2d"), SCORED)
    with pytest.raises(RuntimeError, match="no truth shown"):
        oracle.prepare(None)
    assert list(itertools.islice(left_right_partners([0, 7, 8]), 3)) == [0, 1, 2]


def test_a_2d_oracle_detects_in_every_view_and_a_3d_oracle_measures_once():
    env = gym.make("humotion_gym/BodyTrack2Views-v2", split="test", terminate_on_lost=False)
    env.reset(seed=4)
    base = tracking_env(env)
    truth, poses = _poses(env)
    cams = base.cameras
    assert len(cams) == 2 and cams[0] is base.camera
    flat = OracleSettings("2d", noise_px=1e-9)
    two = TruthOracle(flat, SCORED)
    two.show(truth, base.shape, cams)
    seen = [two.prepare(None), two.prepare(None)]  # each view once, in camera order
    for obs, cam in zip(seen, cams, strict=True):
        want = cam.project(forward_kinematics(truth, base.shape)[SCORED])
        np.testing.assert_allclose(obs.points, want, atol=1e-6)
        np.testing.assert_allclose(
            two.log_likelihood(obs, poses, base.shape, cam),
            _slow(two, obs, poses, base.shape, cam),
            rtol=1e-5,  # sigma 1e-9 px: the truth's own float rounding is a few nats
        )
    assert not np.allclose(seen[0].points, seen[1].points)  # the views differ
    with pytest.raises(RuntimeError, match="another view"):  # views scored out of order
        two.log_likelihood(seen[1], poses, base.shape, cams[0])
    three = TruthOracle(OracleSettings("3d", noise_mm=10.0), SCORED, seed=1)
    three.show(truth, base.shape, cams)
    first, second = three.prepare(None), three.prepare(None)
    assert first.counts and not second.counts
    assert np.all(three.log_likelihood(second, poses, base.shape, cams[1]) == 0.0)
    assert three.log_likelihood(first, poses, base.shape, cams[0])[1:].max() < 0.0
    # one view: the observation the monocular oracle always drew
    one, alone = TruthOracle(flat, SCORED), TruthOracle(flat, SCORED)
    np.testing.assert_array_equal(
        one.show(truth, base.shape, cams[:1]).points, alone.show(truth, base.shape, cams[0]).points
    )
    env.close()


def test_cli_oracle_says_what_is_wrong_with_a_broken_settings_file(monkeypatch, capsys):
    # The agents' settings are read when baselines.agents is imported; a broken
    # file's message reaches the user (argparse would say "invalid value").
    import sys
    import types
    from pathlib import Path

    from baselines.agents.settings import SettingsError

    class Broken(types.ModuleType):
        def __getattr__(self, name: str):
            raise SettingsError(Path("pf.yml"), "pf-cv.fit.damping", "must be a number")

    monkeypatch.setitem(sys.modules, "baselines.agents", Broken("baselines.agents"))
    assert main(["oracle", "--particles", "5", "--agents", "pf-cv"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "pf.yml: pf-cv.fit.damping: must be a number" in err


def test_an_agent_a_later_task_refuses_stops_the_run_before_any_episode(monkeypatch, capsys):
    import baselines.diagnostics.split as split

    ran = []
    monkeypatch.setattr(split, "run_split", lambda *args, **kwargs: ran.append(args))
    argv = ["oracle", "--task", "WalkTrack-v2", "BodyTrack-v2", "--agents", "pf-pca",
            "--particles", "10", "--episodes", "1"]  # fmt: skip
    assert main(argv) == 1
    assert not ran and "cannot track 'BodyTrack-v2'" in capsys.readouterr().err


@pytest.mark.parametrize("text", ["2d:", "3d:mm", "depth", "2d:abc"])
def test_a_likelihood_name_with_a_missing_or_bad_noise_is_refused(text):
    with pytest.raises(ValueError, match=f"likelihood {text!r}"):
        parse_oracle(text)


def test_a_run_of_hold_alone_reports_no_empty_split_table():
    out = run_split("ArmTrack-v2", ["hold"], [None], particles=10, episodes=1, progress=False)
    report = markdown_report([out])
    assert "| hold |" in report and "evidence: image - 2D" not in report


def test_a_run_of_the_validation_persons_names_them_in_its_heading(capsys):
    """``--split validation`` wrote the heading of a test run: nothing said whose episodes."""
    from baselines.experiments.selection import validation_library

    fold = validation_library(None)
    persons = ", ".join(sorted(fold.held_out))
    kwargs = {"episode_frames": 3}
    out = run_split("ArmTrack-v2", ["hold"], [None], particles=10, episodes=1, declared=False,
                    env_kwargs={**kwargs, "library": fold}, progress=False)  # fmt: skip
    assert out["validation_persons"] == sorted(fold.held_out)
    assert markdown_report([out]).startswith(
        f"## ArmTrack-v2: 1 seeded episodes of the validation persons {persons}, 10 particles"
    )
    test = run_split("ArmTrack-v2", ["hold"], [None], particles=10, episodes=1, declared=False,
                     env_kwargs=kwargs, progress=False)  # fmt: skip
    assert "validation_persons" not in test
    assert markdown_report([test]).startswith("## ArmTrack-v2: 1 seeded episodes, 10 particles")
    argv = ["oracle", "--task", "ArmTrack-v2", "--agents", "hold", "--particles", "10",
            "--episodes", "1", "--split", "validation"]  # fmt: skip
    assert main(argv) == 0
    assert f"1 seeded episodes of the validation persons {persons}," in capsys.readouterr().out


def test_split_table_on_set_numbers():
    """Evidence is image - 2D, identity unlabelled - 2D, depth the 2D run's; the first of a kind."""

    def row(agent, kind, likelihood, error, split=(0.0, 0.0, 0.0, 0.0)):
        names = ("along_abs_mm", "across_mm", "aligned_along_abs_mm", "aligned_across_mm")
        oracle = None if kind is None else {"kind": kind}
        return {"agent": agent, "oracle": oracle, "likelihood": likelihood, "error_mm": error,
                **dict(zip(names, split, strict=True))}  # fmt: skip

    rows = [
        row("hold", None, "none", 500.0),
        row("pf-cv", None, "image", 100.0),
        row("pf-cv", "2d", "2d 1px", 40.0, (30.0, 7.0, 20.0, 5.0)),
        row("pf-cv", "2d", "2d 4px", 90.0, (80.0, 9.0, 60.0, 8.0)),  # not read: the second 2D
        row("pf-cv", "2d-unlabelled", "2d-unlabelled 3px", 55.0),
        row("pf-cv", "3d", "3d 10mm", 12.0),
    ]
    lines = split_table({"rows": rows}).splitlines()
    assert len(lines) == 3  # header, rule, pf-cv (hold has no split)
    assert lines[2] == "| pf-cv | 100 | 40 | +60 | 30 / 7 (20 / 5) | +15 | 12 |"
