"""The leaderboard engine: same numbers on any engine, resume, failure rows and exit codes."""

from __future__ import annotations

import importlib.util
import json
import pickle
import signal
import socket
from pathlib import Path
from typing import Any

import pytest

from baselines import MAX_PARTICLES
from baselines import agents as agents_module
from baselines.agents import AgentSpec, ParticleFilterAgent
from baselines.cli import main
from baselines.leaderboard import (
    EPISODES_FILE,
    RESULTS_FILE,
    SCHEMA_VERSION,
    TABLE_FILE,
    ResultsFolder,
    ResumeError,
    run_leaderboard,
)
from baselines.leaderboard.engine import run_cell_episode
from humotion_gym.cli import Terminated, terminated_as_interrupt

# A small leaderboard: hold, a seeded random agent and a particle filter on the
# built-in synthetic data, 3 short episodes per cell.
TASKS = ["BodyTrack-v2"]
AGENTS = ["pf-cv", "random"]
PARTICLES = [20]
EPISODES = 3
SEED = 5


def _numbers(value: Any) -> Any:
    """Everything but the timings (``ms_per_frame``), which differ run to run."""
    if isinstance(value, dict):
        return {k: _numbers(v) for k, v in value.items() if k != "ms_per_frame"}
    if isinstance(value, list):
        return [_numbers(v) for v in value]
    return value


def _run(**kwargs: Any) -> list[dict[str, Any]]:
    return run_leaderboard(
        TASKS, AGENTS, PARTICLES, episodes=EPISODES, seed=SEED, progress=False, **kwargs
    )


@pytest.fixture(scope="module")
def inprocess_rows() -> list[dict[str, Any]]:
    return _run()


def test_the_small_leaderboard_runs_every_cell(inprocess_rows):
    assert [(r["task"], r["agent"], r["particles"]) for r in inprocess_rows] == [
        ("BodyTrack-v2", "hold", 0),
        ("BodyTrack-v2", "pf-cv", 20),
        ("BodyTrack-v2", "random", 0),
    ]
    for row in inprocess_rows:
        assert [e["seed"] for e in row["episodes"]] == list(range(SEED, SEED + EPISODES))
        assert row["summary"]["episodes"] == EPISODES


@pytest.mark.skipif(
    importlib.util.find_spec("ray") is None,
    reason="ray is not installed (the distributed extra: pip install -e '.[distributed]')",
)
def test_ray_with_two_workers_gives_the_in_process_numbers_bit_for_bit(inprocess_rows, monkeypatch):
    # Agents registered in this process only: the workers build them by name.
    from baselines.agents import REFERENCES, HoldAgent, register_agent, register_reference

    class StillAgent(HoldAgent):  # a local class: the workers cannot import it by name
        pass

    monkeypatch.setitem(agents_module.AGENTS, "pf-cv-mine", agents_module.AGENTS["pf-cv"])
    del agents_module.AGENTS["pf-cv-mine"]  # removed again after the test
    register_agent("pf-cv-mine", agents_module.AGENTS["pf-cv"])
    monkeypatch.setitem(REFERENCES, "still-mine", (StillAgent, "hold, by another name"))
    del REFERENCES["still-mine"]
    register_reference("still-mine", StillAgent)
    import ray

    real_shutdown, checked = ray.shutdown, []

    def shutdown() -> None:  # after the run, before Ray stops: the handler ray.init left
        with pytest.raises(Terminated):
            signal.raise_signal(signal.SIGTERM)
        checked.append(True)
        real_shutdown()

    monkeypatch.setattr(ray, "shutdown", shutdown)
    with terminated_as_interrupt():  # as the console scripts run a command
        rows = run_leaderboard(
            TASKS, [*AGENTS, "pf-cv-mine", "still-mine"], PARTICLES, episodes=EPISODES,
            seed=SEED, progress=False, engine="ray", workers=2,
        )  # fmt: skip
        # ray.init's C++ handler would dump a stack and kill the process, and
        # ray.shutdown's default kill it silently; the program's own handler got
        # SIGTERM back from both (Terminated: the run saved, exit 143)
        with pytest.raises(Terminated):
            signal.raise_signal(signal.SIGTERM)
    assert checked == [True]
    mine = {r["agent"]: r for r in rows if r["agent"].endswith("-mine")}
    rows = [r for r in rows if not r["agent"].endswith("-mine")]
    assert _numbers(rows) == _numbers(inprocess_rows)
    by_agent = {r["agent"]: _numbers(r) for r in inprocess_rows}
    for name, same in (("pf-cv-mine", "pf-cv"), ("still-mine", "hold")):
        assert "error" not in mine[name] and mine[name]["summary"]["episodes"] == EPISODES
        got = [e["errors_mm"] for e in mine[name]["episodes"]]
        assert got == [e["errors_mm"] for e in by_agent[same]["episodes"]]
    # the timings are real measurements, not copied
    assert all(r["summary"]["ms_per_frame"] > 0 for r in rows if r["agent"] != "hold")


def test_an_episode_alone_gives_the_numbers_it_gave_in_its_cell(inprocess_rows):
    # episodes do not depend on the ones run before them in the same agent
    for row in inprocess_rows[1:]:
        last = row["episodes"][-1]
        alone = run_cell_episode(
            row["task"], row["agent"], row["particles"], last["seed"], SEED
        ).to_dict()
        assert _numbers(alone) == _numbers(last)


def test_a_run_in_reverse_cell_order_gives_the_same_numbers(inprocess_rows):
    rows = run_leaderboard(
        TASKS, AGENTS[::-1], PARTICLES, episodes=EPISODES, seed=SEED, progress=False
    )
    by_cell = {(r["agent"], r["particles"]): _numbers(r) for r in rows}
    for r in inprocess_rows:
        assert by_cell[(r["agent"], r["particles"])] == _numbers(r)


def _lines(folder: Path) -> list[dict[str, Any]]:
    return [json.loads(line) for line in (folder / EPISODES_FILE).read_text().splitlines()]


def test_resume_runs_only_the_missing_episodes_and_ends_with_the_same_results(
    tmp_path, inprocess_rows
):
    out = tmp_path / "lb"
    # No report (its figures take a second a run; test_stats_report checks it)
    run_leaderboard(
        TASKS, AGENTS, PARTICLES, episodes=2, seed=SEED, progress=False, out=out, report=False
    )
    assert len(_lines(out)) == 2 * len(inprocess_rows)
    # an interruption mid-write leaves a cut line: it is dropped and its episode rerun
    with open(out / EPISODES_FILE, "ab") as fh:
        fh.write(b'{"task": "BodyTrack-v2", "agent": "pf-cv", "partic')
    rows = _run(out=out, resume=True, report=False)
    records = _lines(out)
    assert len(records) == EPISODES * len(inprocess_rows)  # each missing episode ran once
    assert sorted((r["agent"], r["seed"]) for r in records[-len(inprocess_rows) :]) == sorted(
        (r["agent"], SEED + EPISODES - 1) for r in inprocess_rows
    )
    assert _numbers(rows) == _numbers(inprocess_rows)
    saved = json.loads((out / RESULTS_FILE).read_text())
    assert saved["schema_version"] == SCHEMA_VERSION
    assert saved["seed"] == SEED and saved["config"]["episodes"] == EPISODES
    assert _numbers(saved["rows"]) == _numbers(inprocess_rows)
    assert "| pf-cv | 20 |" in (out / TABLE_FILE).read_text()
    # a second resume has nothing left to run
    _run(out=out, resume=True, report=False)
    assert len(_lines(out)) == len(records)


def test_a_results_folder_is_not_overwritten_nor_resumed_with_other_settings(tmp_path):
    out = tmp_path / "lb"
    run_leaderboard(
        ["BodyTrack-v2"], ["hold"], [1], episodes=1, progress=False, out=out, report=False
    )
    with pytest.raises(FileExistsError, match="--resume"):
        run_leaderboard(["BodyTrack-v2"], ["hold"], [1], episodes=1, progress=False, out=out)
    with pytest.raises(ResumeError, match="seed"):
        run_leaderboard(
            ["BodyTrack-v2"], ["hold"], [1], episodes=1, seed=1, progress=False, out=out,
            resume=True,
        )  # fmt: skip
    # drawn episodes and declared windows share their seeds: never one table
    with pytest.raises(ResumeError, match="declared: saved False, now True"):
        run_leaderboard(
            ["BodyTrack-v2"], ["hold"], [1], episodes=1, progress=False, out=out, resume=True,
            declared=True,
        )  # fmt: skip
    # nor two versions of the code
    saved = json.loads((out / "run.json").read_text())
    (out / "run.json").write_text(json.dumps({**saved, "commit": "0123abc-dirty"}))
    with pytest.raises(ResumeError, match=r"commit: saved '0123abc-dirty'.*git checkout 0123abc\)"):
        run_leaderboard(["BodyTrack-v2"], ["hold"], [1], episodes=1, progress=False, out=out,
                        resume=True)  # fmt: skip
    with pytest.raises(FileNotFoundError, match="no run to resume"):
        ResultsFolder(tmp_path / "empty").start({"seed": 0}, resume=True)
    # damaged settings name their file; episodes without their settings cannot be resumed
    folder = ResultsFolder(out)
    folder.run_path.write_text("{cut")
    with pytest.raises(ValueError, match="run.json: not the run's settings"):
        folder.start({"seed": 0}, resume=True)
    folder.run_path.unlink()
    with pytest.raises(FileNotFoundError, match="missing, so the episodes"):
        folder.start({"seed": 0}, resume=True)


def test_a_setting_the_saved_run_lacks_is_a_difference(tmp_path):
    """A run.json written without a setting (an older run) is not resumed as if it agreed."""
    folder = ResultsFolder(tmp_path / "lb")
    assert folder.start({"seed": 0, "declared": False}, resume=False) == []
    folder.append({"task": "ArmTrack-v2", "result": {"seed": 0}})
    folder.append({"task": "ArmTrack-v2", "error": "boom"})  # failed: retried, not returned
    assert folder.start({"seed": 0, "declared": False}, resume=True) == [
        {"task": "ArmTrack-v2", "result": {"seed": 0}}
    ]
    folder.run_path.write_text(json.dumps({"seed": 0}))
    with pytest.raises(ResumeError, match="declared: saved None, now False"):
        folder.start({"seed": 0, "declared": False}, resume=True)


def test_a_damaged_record_is_refused_before_any_episode_runs(tmp_path):
    out = tmp_path / "lb"
    run_leaderboard(
        ["ArmTrack-v2"], ["hold"], [1], episodes=2, progress=False, out=out, report=False
    )
    records = _lines(out)
    records[1]["result"] = {"seed": 1}
    (out / EPISODES_FILE).write_text("".join(json.dumps(r) + "\n" for r in records))
    with pytest.raises(ValueError, match=r"episodes.jsonl: the record of hold .* seed 1, is not"):
        run_leaderboard(["ArmTrack-v2"], ["hold"], [1], episodes=3, progress=False, out=out,
                        resume=True)  # fmt: skip
    assert len(_lines(out)) == 2  # nothing ran


def test_an_address_where_no_ray_listens_is_one_line(tmp_path, capsys):
    pytest.importorskip("ray")
    with socket.socket() as probe:  # a port just freed: nothing listens there
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    argv = [*_cli(tmp_path, "hold"), "--engine", "ray", "--address", f"127.0.0.1:{port}"]
    assert main(argv) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("humotion-gym leaderboard: error: --address 127.0.0.1:")
    assert "no Ray cluster answers there" in err and len(err.splitlines()) == 1


def test_an_address_where_a_web_server_answers_is_no_ray_cluster(monkeypatch):
    import http.server
    import threading

    from baselines.leaderboard.ray_setup import NoRayCluster, check_ray_address

    # Ray's dashboard (8265), which `ray start` prints beside the cluster's address:
    # Ray retried it for minutes
    web = http.server.HTTPServer(("127.0.0.1", 0), http.server.BaseHTTPRequestHandler)
    threading.Thread(target=web.handle_request, daemon=True).start()
    with pytest.raises(NoRayCluster, match="a web server answers there"):
        check_ray_address(f"127.0.0.1:{web.server_address[1]}", timeout=5.0)
    web.server_close()
    # a port that takes the connection and says nothing to HTTP (as a gRPC server
    # waiting for its own preface) is left to Ray
    with socket.socket() as quiet:
        quiet.bind(("127.0.0.1", 0))
        quiet.listen()
        check_ray_address(f"127.0.0.1:{quiet.getsockname()[1]}", timeout=0.5)

    # a connection that times out is no cluster (the HTTP probe's timeout is not it)
    def unreachable(*args, **kwargs):
        raise TimeoutError("timed out")

    monkeypatch.setattr(socket, "create_connection", unreachable)
    with pytest.raises(NoRayCluster, match="no Ray cluster answers there"):
        check_ray_address("10.0.0.9:6379", timeout=0.5)


def test_the_data_resume_the_same_named_either_way(tmp_path, monkeypatch, shared_mocap):
    out = tmp_path / "lb"
    arm = ["ArmTrack-v2"]
    run_leaderboard(arm, ["hold"], [1], episodes=1, progress=False, out=out, report=False,
                    env_kwargs={"data_dir": str(shared_mocap)})  # fmt: skip
    monkeypatch.setenv("HUMOTION_MOCAP", str(shared_mocap))
    run_leaderboard(arm, ["hold"], [1], episodes=2, progress=False, out=out, resume=True,
                    report=False)  # fmt: skip
    monkeypatch.delenv("HUMOTION_MOCAP")
    with pytest.raises(ResumeError, match="data: saved"):  # the synthetic set is other data
        run_leaderboard(arm, ["hold"], [1], episodes=2, progress=False, out=out, resume=True)


def _cli(tmp_path: Path, *agents: str) -> list[str]:
    # No report: its figures take a second a run, and test_stats_report checks it
    return [
        "leaderboard", "--tasks", "BodyTrack-v2", "--agents", *agents, "--particles", "10",
        "--episodes", "1", "--out", str(tmp_path / "lb"), "--no-report",
    ]  # fmt: skip


def test_an_agent_that_does_not_cover_a_task_is_a_row_with_its_reason_and_exit_0(tmp_path, capsys):
    assert main(_cli(tmp_path, "pf-slds")) == 0
    out = capsys.readouterr().out
    assert "| pf-slds | 10 | skipped: pf-slds supports the tasks" in out
    rows = json.loads((tmp_path / "lb" / RESULTS_FILE).read_text())["rows"]
    assert [r["agent"] for r in rows if "skipped" in r] == ["pf-slds"]


def test_an_agent_whose_prior_fails_to_fit_is_an_error_row_and_exit_1(
    tmp_path, capsys, monkeypatch
):
    broken = AgentSpec("baselines.priors.constant_velocity", {"no_such_setting": 1.0})
    monkeypatch.setitem(agents_module.AGENTS, "pf-broken", broken)
    assert main(_cli(tmp_path, "pf-broken", "pf-cv")) == 1
    captured = capsys.readouterr()
    assert "| pf-broken | 10 | ERROR: building it failed: ValueError" in captured.out
    assert "error: pf-broken on BodyTrack-v2" in captured.err
    rows = json.loads((tmp_path / "lb" / RESULTS_FILE).read_text())["rows"]
    assert {r["agent"]: ("error" in r) for r in rows} == {
        "hold": False, "pf-broken": True, "pf-cv": False,
    }  # fmt: skip


def test_an_agent_that_raises_in_an_episode_is_an_error_row_and_exit_1(
    tmp_path, capsys, monkeypatch
):
    def predict(self, *args, **kwargs):
        raise FloatingPointError("the filter's weights are all zero")

    monkeypatch.setattr(ParticleFilterAgent, "predict", predict)
    assert main(_cli(tmp_path, "pf-cv")) == 1
    captured = capsys.readouterr()
    assert "ERROR: episode 0 raised FloatingPointError" in captured.out
    rows = json.loads((tmp_path / "lb" / RESULTS_FILE).read_text())["rows"]
    assert rows[0]["agent"] == "hold" and "summary" in rows[0]
    assert rows[1]["failed_seeds"] == [0]
    # an agent that only failed may leave the grid of the resumed run
    lines = (tmp_path / "lb" / EPISODES_FILE).read_text()
    assert main([*_cli(tmp_path, "hold"), "--resume"]) == 0
    (tmp_path / "lb" / EPISODES_FILE).write_text(lines)
    # the failed episode is recorded but not done: a resume retries it
    monkeypatch.undo()
    assert main([*_cli(tmp_path, "pf-cv"), "--resume"]) == 0
    rows = json.loads((tmp_path / "lb" / RESULTS_FILE).read_text())["rows"]
    assert all("summary" in r for r in rows)


@pytest.mark.parametrize(
    "extra, flag",
    [
        (["--resume"], "--resume"),
        (["--workers", "2"], "--workers"),
        (["--address", "x"], "--address"),
    ],
)
def test_engine_flags_used_wrongly_are_usage_errors(extra, flag, capsys):
    argv = ["leaderboard", "--tasks", "BodyTrack-v2", "--agents", "hold", "--episodes", "1"]
    assert main(argv + extra) == 2
    err = capsys.readouterr().err
    assert flag in err and ("--workers" in err) == (flag == "--workers")  # the flag given
    bad = ["--engine", "ray", "--address", "garbage"]
    assert main(argv + bad) == 2  # before Ray starts
    assert "--address 'garbage': expected HOST:PORT, ray://HOST:PORT" in capsys.readouterr().err


class _FakeRay:
    """Just enough of Ray for :class:`RayEngine` to start and stop actors, recording its calls."""

    def __init__(self, cpus: int, up: bool = False, fail_init: bool = False) -> None:
        self.cpus, self.up, self.fail_init = cpus, up, fail_init
        self.inits: list[dict] = []
        self.shutdowns = 0
        self.actors = 0

    def is_initialized(self) -> bool:
        return self.up

    def init(self, **kwargs) -> None:
        self.inits.append(kwargs)
        self.up = True
        if self.fail_init:
            raise KeyboardInterrupt  # Ctrl-C while Ray starts

    def cluster_resources(self) -> dict:
        return {"CPU": float(self.cpus)}

    def remote(self, num_cpus: int):
        fake = self

        class Actor:
            @staticmethod
            def remote(*args):
                fake.actors += 1
                return object()

        return lambda cls: Actor

    def kill(self, actor) -> None:
        self.actors -= 1

    def shutdown(self) -> None:
        self.shutdowns += 1
        self.up = False


def test_a_ray_of_its_own_beside_a_cluster_no_more_actors_than_episodes(monkeypatch):
    from baselines.leaderboard import engine as engine_module

    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    fake = _FakeRay(cpus=3)
    monkeypatch.setattr(engine_module, "_import_ray", lambda: fake)
    runner = engine_module.RayEngine(0, {}, workers=8, jobs=3)
    # "local" starts a Ray of this run even where `ray start` left a cluster
    assert fake.inits[0]["address"] == "local" and fake.inits[0]["num_cpus"] == 3
    assert runner.workers == fake.actors == 3  # 8 asked, 3 episodes to run
    runner.close()
    assert fake.actors == 0 and fake.shutdowns == 1
    # a joined cluster too small for the workers asked: refused, not waited on for ever
    joined = _FakeRay(cpus=2, up=True)
    monkeypatch.setattr(engine_module, "_import_ray", lambda: joined)
    with pytest.raises(engine_module.BadWorkers, match="4 workers .* has 2 CPUs"):
        engine_module.RayEngine(0, {}, workers=4, jobs=10)
    assert joined.actors == 0 and joined.shutdowns == 0  # not ours to stop
    # interrupted while starting: the Ray it started is stopped
    broken = _FakeRay(cpus=2, fail_init=True)
    monkeypatch.setattr(engine_module, "_import_ray", lambda: broken)
    with pytest.raises(KeyboardInterrupt):
        engine_module.RayEngine(0, {}, workers=2)
    assert broken.shutdowns == 1


def test_the_ray_schedule_hands_out_every_episode_once_keeping_workers_on_their_cells():
    from baselines.leaderboard.engine import Cell, Episode, _Schedule

    cells = [Cell("BodyTrack-v2", a, 10) for a in ("a", "b", "c")]
    episodes = [Episode(c, s) for c in cells for s in range(4)]
    schedule = _Schedule(episodes)
    given: dict[int, list[Episode]] = {0: [], 1: []}
    slot = 0
    while schedule:
        episode = schedule.next(slot)
        assert episode is not None
        given[slot].append(episode)
        slot = 1 - slot
    assert schedule.next(0) is None
    assert sorted(given[0] + given[1], key=lambda e: (e.cell, e.seed)) == episodes
    # each worker starts on a cell of its own and stays on it while it lasts
    assert {e.cell for e in given[0][:4]} == {cells[0]}
    assert {e.cell for e in given[1][:4]} == {cells[1]}


def test_an_interrupted_run_exits_130_keeps_its_episodes_and_resumes(tmp_path, capsys, monkeypatch):
    import baselines.leaderboard.engine as engine

    real, calls = engine.run_episode, []

    def interrupted_after_three(*args, **kwargs):
        calls.append(1)
        if len(calls) > 3:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    monkeypatch.setattr(engine, "run_episode", interrupted_after_three)
    argv = [*_cli(tmp_path, "pf-cv", "random"), "--episodes", "2"]
    assert main(argv) == 130
    err = capsys.readouterr().err  # (the progress bars' lines besides)
    said = [line for line in err.splitlines() if "interrupted" in line or "--resume" in line]
    assert len(said) == 1 and said[0].startswith("humotion-gym leaderboard: interrupted; ")
    assert said[0].endswith(" --resume")
    assert len(_lines(tmp_path / "lb")) == 3
    monkeypatch.undo()
    assert main([*argv, "--resume"]) == 0
    assert "resuming: 3 episodes were done, 3 to run" in capsys.readouterr().err
    assert len(_lines(tmp_path / "lb")) == 6


def test_one_data_folder_is_saved_as_the_command_line_gives_it(tmp_path):
    from baselines.leaderboard.engine import resolve_env_kwargs

    one = resolve_env_kwargs({"data_dir": str(tmp_path), "noise": 2.0})
    assert one == resolve_env_kwargs({"data_dir": [tmp_path], "noise": 2.0})
    assert one["data_dir"] == [str(tmp_path.resolve())]


@pytest.mark.parametrize(
    "kwargs, name",
    [({"seed": -1}, "seed"), ({"episodes": 2.5}, "episodes"), ({"episodes": True}, "episodes"),
     ({"particles": [10, 0]}, r"particles\[1\]"), ({"agent_seeds": 0}, "agent_seeds")],
)  # fmt: skip
def test_a_runs_counts_are_refused_by_name_before_any_work(kwargs, name):
    args = {"episodes": 1, "particles": [10], "progress": False, **kwargs}
    with pytest.raises(ValueError, match=f"^{name}: expected an integer"):
        run_leaderboard(["BodyTrack-v2"], ["hold"], **args)


def test_the_most_particles_are_taken_and_one_more_refused():
    # at most MAX_PARTICLES: the run gets past the count to the next check, the engine's
    args = {"episodes": 1, "progress": False, "engine": "no-such-engine"}
    with pytest.raises(ValueError, match="^engine: expected one of"):
        run_leaderboard(["BodyTrack-v2"], ["hold"], [MAX_PARTICLES], **args)
    with pytest.raises(ValueError, match=r"^particles\[0\]: expected at most"):
        run_leaderboard(["BodyTrack-v2"], ["hold"], [MAX_PARTICLES + 1], **args)


#: One short hold episode per seed, on small frames: resumes compared with their records.
SMALL = {"env_kwargs": {"episode_frames": 4, "width": 64, "height": 64}, "progress": False,
         "report": False, "seed": 3}  # fmt: skip


def test_records_without_their_agent_seed_ran_with_the_runs_seed(tmp_path):
    """Records saved before they named their agent seed resume as the run's seed's, not 0's."""
    out = tmp_path / "lb"
    run_leaderboard(["ArmTrack-v2"], ["hold"], [1], episodes=2, out=out, **SMALL)
    records = _lines(out)
    assert [r["agent_seed"] for r in records] == [3, 3]
    old = [{k: v for k, v in r.items() if k != "agent_seed"} for r in records]
    (out / EPISODES_FILE).write_text("".join(json.dumps(r) + "\n" for r in old))
    run_leaderboard(["ArmTrack-v2"], ["hold"], [1], episodes=2, out=out, resume=True, **SMALL)
    assert _lines(out) == old  # nothing ran again


def test_a_resume_with_fewer_agent_seeds_names_the_count_to_resume_with(tmp_path):
    out = tmp_path / "lb"
    run_leaderboard(["ArmTrack-v2"], ["hold"], [1], 1, out=out, agent_seeds=2, **SMALL)
    assert sorted(r["agent_seed"] for r in _lines(out)) == [3, 4]  # from the run's seed
    with pytest.raises(ResumeError, match=r"agent seeds \[4\] beyond this run's \[3\]; resume "
                       r"with --agent-seeds 2 \(agent_seeds=2\)"):  # fmt: skip
        run_leaderboard(["ArmTrack-v2"], ["hold"], [1], 1, out=out, resume=True, **SMALL)


def test_an_error_row_names_its_first_failed_episode(monkeypatch):
    def predict(self, *args, **kwargs):
        raise FloatingPointError("the filter's weights are all zero")

    monkeypatch.setattr(ParticleFilterAgent, "predict", predict)
    rows = run_leaderboard(["ArmTrack-v2"], ["pf-cv"], [10], 3, **SMALL)
    assert rows[1]["failed_seeds"] == [3, 4, 5]
    assert rows[1]["error"].startswith("episode 3 raised FloatingPointError")


def test_a_difficulty_given_at_the_tasks_own_value_resumes_either_way(tmp_path, capsys):
    """--noise 4 is every task's own noise: no setting, so a run without it resumes with it."""
    argv = ["leaderboard", "--tasks", "ArmTrack-v2", "--agents", "hold", "--particles", "1",
            "--episodes", "1", "--out", str(tmp_path / "lb"), "--no-report"]  # fmt: skip
    assert main(argv) == 0
    assert main([*argv, "--episodes", "2", "--noise", "4", "--background", "clutter",
                 "--resume"]) == 0  # fmt: skip
    saved = json.loads((tmp_path / "lb" / "run.json").read_text())
    assert "noise" not in saved["env_kwargs"] and "background" not in saved["env_kwargs"]
    capsys.readouterr()
    assert main([*argv, "--episodes", "2", "--noise", "8", "--resume"]) == 2  # another noise
    assert "noise" in capsys.readouterr().err


def test_the_leaderboard_tracks_the_test_split_only(tmp_path):
    """A split in env_kwargs would score training persons as a table's test episodes."""
    with pytest.raises(ValueError, match="split='train', but the leaderboard tracks the test"):
        run_leaderboard(["ArmTrack-v2"], ["hold"], [1], episodes=1, progress=False,
                        env_kwargs={"split": "train"})  # fmt: skip


def test_resume_with_other_seeds_and_a_report_flag_without_out_say_what_is_wrong(tmp_path, capsys):
    argv = [*_cli(tmp_path, "hold"), "--episodes", "2"]
    assert main(argv) == 0
    capsys.readouterr()
    assert main([*argv, "--seed", "7", "--resume"]) == 2
    err = capsys.readouterr().err
    assert "holds episodes of seeds 0, 1, outside this run's 7-8 (--seed 7, --episodes 2)" in err
    no_out = ["leaderboard", "--tasks", "BodyTrack-v2", "--agents", "hold", "--no-report"]
    assert main(no_out) == 2
    assert "--no-report: needs --out FOLDER" in capsys.readouterr().err
    assert main(["leaderboard", "--tasks", "BodyTrack-v2", "--agents", "nope"]) == 2
    assert "described by humotion-gym agents (one of yours needs --import MODULE) (see" in (
        capsys.readouterr().err
    )


def test_longer_episodes_than_the_tasks_run_to_their_end():
    """episode_frames above the task's: gym.make's TimeLimit must not cut them."""
    rows = run_leaderboard(
        TASKS, ["hold"], [1], episodes=1, seed=SEED, progress=False,
        env_kwargs={"episode_frames": 35},
    )  # fmt: skip
    assert len(rows[0]["episodes"][0]["errors_mm"]) == 35


def test_a_worker_that_cannot_take_the_registered_agents_stops_the_run_in_one_line(monkeypatch):
    from types import SimpleNamespace

    from baselines.leaderboard import engine as engine_module

    class TaskError(Exception):
        def __init__(self, cause: BaseException) -> None:
            super().__init__(str(cause))
            self.cause = cause

    class Unpicklable(_FakeRay):
        exceptions = SimpleNamespace(RayTaskError=TaskError)
        cloudpickle = pickle

        def remote(self, num_cpus: int):
            actor = SimpleNamespace(
                start=SimpleNamespace(remote=lambda *args: None), run=None
            )  # fmt: skip
            return lambda cls: SimpleNamespace(remote=lambda *args: actor)

        def put(self, value):
            return value

        def get(self, refs):
            raise TaskError(ModuleNotFoundError("No module named 'mine'\nTraceback ..."))

    class Started(Unpicklable):
        def get(self, refs):
            return [(engine_module.package_version(), 1) for _ in refs]

    from baselines.agents import REFERENCES, HoldAgent

    class Locked(HoldAgent):  # a local class, which pickle (this fake's) cannot send
        pass

    monkeypatch.setitem(REFERENCES, "locked-x", (Locked, ""))
    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    monkeypatch.setattr(engine_module, "_import_ray", lambda: Started(cpus=2))
    # only the run's agents are sent: one that cannot be, registered but not run, is no matter
    engine_module.RayEngine(0, {}, workers=2, jobs=2).start({}, ["hold", "pf-cv+bc"])
    with pytest.raises(engine_module.WorkerStartError, match=r"cannot be sent to the workers"):
        engine_module.RayEngine(0, {}, workers=2, jobs=2).start({}, ["locked-x"])
    monkeypatch.setattr(engine_module, "_import_ray", lambda: Unpicklable(cpus=2))
    runner = engine_module.RayEngine(0, {}, workers=2, jobs=2)
    with pytest.raises(engine_module.WorkerStartError) as caught:
        runner.start({}, ["hold"])
    message = str(caught.value)
    assert message == (
        "a Ray worker could not start (ModuleNotFoundError: No module named 'mine'); define the "
        "agents you register in a module the workers can import"
    )


def test_rays_token_note_is_kept_out_and_its_warning_that_auth_is_off_kept(caplog):
    import logging

    from baselines.leaderboard import ray_setup

    ray_setup.quiet_token_note()
    ray_setup.quiet_token_note()
    logger = logging.getLogger(ray_setup._TOKEN_LOGGER)
    assert logger.filters.count(ray_setup._TOKEN_NOTE_FILTER) == 1
    with caplog.at_level(logging.WARNING, logger=ray_setup._TOKEN_LOGGER):
        logger.warning("Token authentication is enabled for this Ray cluster. Set ...")
        logger.warning("Token authentication is disabled for this Ray cluster. Anyone ...")
    assert [r.getMessage().split(" for ")[0] for r in caplog.records] == [
        "Token authentication is disabled"
    ]
