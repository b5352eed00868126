"""The engine's runner, shipped fits and schedule (``baselines.leaderboard.engine``), in-process.

Short episodes on small frames of the built-in synthetic data, as the engine
tests' ``SMALL`` runs.
"""

from __future__ import annotations

from typing import Any

import pytest
from test_leaderboard_engine import _numbers  # a result less its timings

from baselines.agents import tracking_env
from baselines.leaderboard import engine
from baselines.leaderboard.engine import (
    Cell,
    Episode,
    EpisodeRunner,
    InProcessEngine,
    _Schedule,
    make_env,
    prepare_cells,
    run_cell_episode,
    window_options,
)

TASK = "ArmTrack-v2"
SMALL = {"episode_frames": 4, "width": 64, "height": 64}


def test_a_declared_window_is_the_episode_run():
    """An episode with a window resets on that clip and start, in the runner and alone."""
    assert window_options(None) is None
    env = make_env(TASK, SMALL)
    base = tracking_env(env)
    clip = base.clips[-1]
    start = int(base._good_starts(clip)[3])
    env.close()
    assert window_options((clip.clip_id, start)) == {"clip_id": clip.clip_id, "start": start}
    runner = EpisodeRunner(0, SMALL)
    record = runner.run(Episode(Cell(TASK, "hold", 0), 5, window=(clip.clip_id, start)))
    runner.close()
    assert (record["result"]["clip_id"], record["result"]["start_frame"]) == (clip.clip_id, start)
    alone = run_cell_episode(TASK, "hold", 0, 5, 0, SMALL, window=(clip.clip_id, start))
    assert (alone.clip_id, alone.start_frame) == (clip.clip_id, start)


def test_each_agent_seed_has_its_own_agent():
    """Two agent seeds of one cell in one runner give what each gives alone."""
    runner = EpisodeRunner(0, SMALL)
    cell = Cell(TASK, "pf-cv", 10)
    records = [runner.run(Episode(cell, 2, agent_seed=a)) for a in (1, 9, 1)]
    runner.close()
    assert [r["agent_seed"] for r in records] == [1, 9, 1]
    for record, agent_seed in zip(records, (1, 9, 1), strict=True):
        alone = run_cell_episode(TASK, "pf-cv", 10, 2, agent_seed, SMALL).to_dict()
        assert _numbers(record["result"]) == _numbers(alone)
    assert records[0]["result"]["errors_mm"] != records[1]["result"]["errors_mm"]


def test_the_runner_keeps_the_most_recently_used_agents():
    """With room for two, the cell used least recently is the one rebuilt."""
    runner = EpisodeRunner(0, SMALL, cached_cells=2)
    a, b, c = (Cell(TASK, "hold", n) for n in (1, 2, 3))
    first_a, first_b = runner._agent(a, 0), runner._agent(b, 0)
    assert runner._agent(a, 0) is first_a  # a used again: b is now the oldest
    runner._agent(c, 0)
    assert len(runner._agents) == 2
    assert runner._agent(a, 0) is first_a  # kept
    assert runner._agent(b, 0) is not first_b  # dropped, rebuilt
    runner.close()


def test_shipped_fits_build_the_filters_and_nothing_is_fitted(monkeypatch):
    """A runner given the driver's fits never builds through ``make``; the numbers are make's."""
    cell = Cell(TASK, "pf-cv", 12)
    fits, problems = prepare_cells([cell], 3, SMALL, progress=False)
    assert problems == {} and set(fits) == {(TASK, "pf-cv")}
    want = run_cell_episode(TASK, "pf-cv", 12, 4, 3, SMALL).to_dict()

    def no_make(*args, **kwargs):
        raise AssertionError("the runner built an agent without its shipped fit")

    monkeypatch.setattr(engine, "make", no_make)
    runner = InProcessEngine(3, SMALL)
    runner.start(fits)
    records: list[dict[str, Any]] = []
    runner.run([Episode(cell, 4)], records.append)
    runner.close()
    assert "error" not in records[0], records[0].get("error")
    assert records[0]["agent_seed"] == 3  # an episode without its own: the runner's seed
    assert _numbers(records[0]["result"]) == _numbers(want)


def test_an_agent_that_raised_is_rebuilt_for_the_next_episode(monkeypatch):
    """A half-run agent is not reused: the failed episode's record, then a fresh agent's."""
    from baselines.agents import REFERENCES, HoldAgent

    made: list[Any] = []

    class Flaky(HoldAgent):
        def __init__(self, *args: Any, **kwargs: Any) -> None:
            super().__init__(*args, **kwargs)
            self.calls = 0
            made.append(self)

        def predict(self, *args: Any, **kwargs: Any) -> Any:
            self.calls += 1
            if len(made) == 1 and self.calls == 3:  # the first episode's first frame
                raise FloatingPointError("half-run")
            return super().predict(*args, **kwargs)

    monkeypatch.setitem(REFERENCES, "flaky-x", (Flaky, ""))
    runner = EpisodeRunner(0, SMALL)
    first, second = (runner.run(Episode(Cell(TASK, "flaky-x", 0), s)) for s in (0, 1))
    runner.close()
    assert first["error"] == "FloatingPointError: half-run" and "Traceback" in first["traceback"]
    assert "result" in second and len(made) == 2  # built again after the error


def test_an_unknown_agent_is_the_callers_mistake_not_an_error_row():
    """prepare_cells lets the KeyError of an unknown name through."""
    with pytest.raises(KeyError):
        prepare_cells([Cell(TASK, "no-such-agent", 1)], 0, SMALL, progress=False)


def test_a_worker_out_of_cells_helps_on_the_one_with_most_left():
    """No cell left unstarted: the next episode is of the cell with the most episodes left."""
    cells = [Cell(TASK, a, 1) for a in ("a", "b", "c")]
    counts = {"a": 1, "b": 3, "c": 6}
    schedule = _Schedule([Episode(c, s) for c in cells for s in range(counts[c.agent])])
    assert [schedule.next(slot).cell.agent for slot in (0, 1, 2)] == ["a", "b", "c"]
    # slot 0's cell is done and every cell started: c has 5 left, b 2
    assert schedule.next(0).cell.agent == "c"


class _Died(Exception):
    """Ray's RayActorError: the actor's process is gone."""


class _Failed(Exception):
    """Ray's RayError: anything else Ray failed at."""


class _Ref:
    """An object reference: a call not yet collected (hashable by identity, as Ray's)."""

    def __init__(self, name: str, args: tuple[Any, ...], actor: Any) -> None:
        self.name, self.args, self.actor = name, args, actor


class _Ray:
    """Ray as RayEngine uses it, in this process: each call checked against the actor's method.

    An episode whose seed is in ``dies`` kills its actor (once; in ``kills``,
    every time it runs), and every call queued on a dead actor fails as Ray's
    do; one in ``fails`` fails in Ray; every other returns a record naming its
    episode.
    """

    exceptions = type("exceptions", (), {"RayActorError": _Died, "RayError": _Failed,
                                         "RayTaskError": _Failed})  # fmt: skip

    def __init__(
        self, dies: set[int] = frozenset(), fails: set[int] = frozenset(),
        kills: set[int] = frozenset(),
    ) -> None:  # fmt: skip
        import pickle

        self.cloudpickle = pickle
        self.dies, self.fails, self.kills = set(dies), set(fails), set(kills)
        self.made: list[Any] = []
        self.started: list[Any] = []

    def is_initialized(self) -> bool:
        return True  # a Ray already up: nothing to start or stop

    def cluster_resources(self) -> dict[str, float]:
        return {"CPU": 2.0}

    def remote(self, num_cpus: int):
        import inspect
        from types import SimpleNamespace

        fake = self

        def method(actor: Any, name: str):
            signature = inspect.signature(getattr(engine._RayWorker, name))

            def remote(*args):
                signature.bind(None, *args)  # Ray refuses a call that does not fit
                if name == "start":
                    fake.started.append(actor)
                return _Ref(name, args, actor)

            return SimpleNamespace(remote=remote)

        def actor_class(cls):
            def make(*args):
                signature = inspect.signature(cls.__init__)
                signature.bind(None, *args)
                actor = SimpleNamespace()
                actor.run, actor.start = method(actor, "run"), method(actor, "start")
                fake.made.append(actor)
                return actor

            return SimpleNamespace(remote=make)

        return actor_class

    def put(self, value: Any) -> Any:
        return value

    def wait(self, refs: list[Any], num_returns: int = 1) -> tuple[list[Any], list[Any]]:
        """Each actor runs its oldest call; the oldest call is done, but a dead actor's
        last queued call fails first (Ray's order among a dead actor's calls varies)."""
        running: dict[int, Any] = {}
        for r in refs:  # in the order they were sent
            running.setdefault(id(r.actor), r)
        for r in running.values():
            if r.name == "run" and r.args[0].seed in self.dies | self.kills:
                self.dies.discard(r.args[0].seed)
                r.actor.dead = True
        dead = [r for r in refs if getattr(r.actor, "dead", False)]
        first = dead[-1] if dead else refs[0]
        return [first], [r for r in refs if r is not first]

    def get(self, ref: Any) -> Any:
        if isinstance(ref, list):
            return [self.get(r) for r in ref]
        name, args = ref.name, ref.args
        if name == "start":
            return engine.package_version(), 1
        episode = args[0]
        if getattr(ref.actor, "dead", False):
            raise _Died("the actor died")
        if episode.seed in self.fails:
            raise _Failed("object lost")
        return {**engine._record(episode, 0), "result": {"seed": episode.seed}, "wall_s": 0.0}

    def kill(self, actor: Any) -> None:
        pass


def _ray_run(monkeypatch: pytest.MonkeyPatch, fake: _Ray, n: int) -> list[dict[str, Any]]:
    monkeypatch.setattr(engine, "_import_ray", lambda: fake)
    runner = engine.RayEngine(0, {}, workers=2, jobs=n)
    runner.start({}, ["hold"])
    records: list[dict[str, Any]] = []
    runner.run([Episode(Cell(TASK, "hold", 0), s) for s in range(n)], records.append)
    assert len(runner.actors) == 2
    runner.close()
    return records


def test_ray_runs_every_episode_once_and_a_ray_failure_is_an_error_record(monkeypatch):
    """Each episode comes back once; one Ray lost is an error record naming Ray's error."""
    records = _ray_run(monkeypatch, _Ray(fails={3}), 7)
    assert sorted(r["seed"] for r in records) == list(range(7))
    lost = [r for r in records if "error" in r]
    assert [(r["seed"], r["error"]) for r in lost] == [(3, "_Failed: object lost")]
    assert all(r["result"] == {"seed": r["seed"]} for r in records if "error" not in r)


def test_a_dead_ray_worker_is_replaced_and_its_episodes_run_again(monkeypatch):
    """A worker dies once: a new one takes its place and runs every episode it held."""
    fake = _Ray(dies={2})
    records = _ray_run(monkeypatch, fake, 6)
    assert sorted(r["seed"] for r in records) == list(range(6))
    assert all(r["result"] == {"seed": r["seed"]} for r in records)  # none lost
    assert len(fake.made) == 3 and fake.made[-1] in fake.started  # replaced once, started


def test_an_episode_that_kills_its_worker_twice_is_a_lost_record(monkeypatch):
    """Episode 2 kills every worker that runs it: lost after two, the rest all run."""
    fake = _Ray(kills={2})
    records = _ray_run(monkeypatch, fake, 6)
    assert sorted(r["seed"] for r in records) == list(range(6))
    lost = [r for r in records if "error" in r]
    assert [r["seed"] for r in lost] == [2]
    assert lost[0]["error"].startswith("the Ray worker died as it ran it, twice")
    assert all(r["result"] == {"seed": r["seed"]} for r in records if "error" not in r)
    assert len(fake.made) == 4 and all(a in fake.started for a in fake.made[2:])  # two replaced


def test_a_joined_cluster_takes_as_many_workers_as_it_has_cpus_and_no_more(monkeypatch):
    """Two CPUs: two workers start, a third would wait for ever and is refused."""
    fake = _Ray()
    monkeypatch.setattr(engine, "_import_ray", lambda: fake)
    engine.RayEngine(0, {}, workers=2, jobs=5).close()
    with pytest.raises(engine.BadWorkers, match="3 workers .* has 2 CPUs"):
        engine.RayEngine(0, {}, workers=3, jobs=5)


def test_the_inprocess_engine_takes_one_worker_here_and_nothing_else():
    """workers other than 1, or an address, are refused by the in-process engine."""
    engine.make_engine("inprocess", 0, SMALL, workers=1).close()
    for bad in ({"workers": 2}, {"address": "localhost:6379"}):
        with pytest.raises(ValueError, match="the inprocess engine runs one worker"):
            engine.make_engine("inprocess", 0, SMALL, **bad)
    with pytest.raises(ValueError, match="engine: expected one of"):
        engine.make_engine("threads", 0, SMALL)


def test_a_worker_that_dies_in_real_ray_is_an_error_row_and_the_run_goes_on(monkeypatch):
    """A real Ray worker exits in an episode, and its replacement too: that agent's row
    names the lost episode, and the rest of the run (on a new worker) comes back whole."""
    pytest.importorskip("ray", reason="the distributed extra (pip install -e '.[distributed]')")
    import os

    from baselines.agents import REFERENCES, HoldAgent, register_reference
    from baselines.leaderboard import run_leaderboard

    class DiesOnSeed2(HoldAgent):  # local: sent to the workers by value
        def seed_episode(self, episode_seed: int) -> None:
            self.episode = int(episode_seed)

        def predict(self, observation, state=None, episode_start=None, deterministic=True):
            if getattr(self, "episode", None) == 2:
                os._exit(1)  # the worker process dies, as one killed by the system would
            return super().predict(observation, state, episode_start, deterministic)

    monkeypatch.setitem(REFERENCES, "dies-mine", (DiesOnSeed2, ""))
    del REFERENCES["dies-mine"]  # registered below, removed again after the test
    register_reference("dies-mine", DiesOnSeed2)
    rows = run_leaderboard(
        [TASK], ["dies-mine", "hold"], [20], episodes=4, seed=0, progress=False,
        engine="ray", workers=1, env_kwargs=SMALL,
    )  # fmt: skip
    by_agent = {r["agent"]: r for r in rows}
    assert by_agent["dies-mine"]["error"].startswith(
        "episode 2 raised the Ray worker died as it ran it, twice"
    )
    assert "error" not in by_agent["hold"]
    assert [e["seed"] for e in by_agent["hold"]["episodes"]] == [0, 1, 2, 3]
