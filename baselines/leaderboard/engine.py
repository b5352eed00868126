"""The leaderboard's engine: episodes as the unit of work, in-process or on Ray.

A leaderboard is a list of **cells** (task, agent, particle count), each run on
the same seeded episodes; the unit of work is one **episode** (a cell and an
episode seed). An :class:`EpisodeRunner` runs episodes, keeping each cell's
environment and agent between them. :class:`InProcessEngine` (the default) runs
one runner in this process; :class:`RayEngine` (the ``distributed`` extra) one
per Ray actor, on a local Ray or an existing cluster.

An episode's result depends on its cell, its seed and the run's settings alone:
:func:`~baselines.leaderboard.evaluation.run_episode` reseeds the agent from
(agent seed, episode seed) and every runner tracks with one BLAS thread, so any
engine and number of workers gives the same numbers, timings aside. Priors are
fitted once, in the driver (:func:`prepare_cells`), and shipped to the runners,
which never fit; hybrids of a filter and a policy read their filter's prior
from the on-disk cache (``HUMOTION_CACHE``).

Every finished episode comes back as a plain-JSON **record**: ``task``,
``agent``, ``particles``, ``seed``, ``agent_seed``, ``wall_s`` (in its worker)
and either ``result`` (:meth:`~baselines.leaderboard.evaluation.EpisodeResult.to_dict`)
or ``error`` (``"Type: message"``) with ``traceback``.
"""

from __future__ import annotations

import importlib
import itertools
import logging
import os
import pickle
import signal
import sys
import threading
import time
import traceback
from collections import OrderedDict, deque
from collections.abc import Callable, Collection, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import cv2
import gymnasium as gym
import numpy as np
from numpy.typing import NDArray
from tqdm.auto import tqdm

import humotion_gym  # noqa: F401  (registers the environment ids, in Ray workers too)
from baselines.agents import (
    AGENTS,
    REFERENCES,
    ParticleFilterAgent,
    TaskNotSupported,
    filter_agent,
    make,
    tracking_env,
)
from baselines.leaderboard.evaluation import EpisodeResult, run_episode, warm_up
from baselines.leaderboard.ray_setup import check_ray_address, quiet_token_note
from humotion_gym.envs import episodes
from humotion_gym.mocap.library import package_version
from humotion_gym.threads import limit_blas_threads, single_threaded_blas

#: The engines by name (``--engine``).
ENGINES: tuple[str, ...] = ("inprocess", "ray")
#: Episodes queued per Ray actor: one running, one waiting, so an actor never
#: idles while the driver collects a result and sends the next episode.
QUEUE_DEPTH = 2
#: Cells whose environment and agent a runner keeps (least recently used
#: dropped first). Episodes are dispatched cell by cell, so a few suffice.
CACHED_CELLS = 8
#: Environment variables handed to Ray workers (the prior cache, the mocap
#: folder and the BLAS threads), where set in the driver.
WORKER_ENV_VARS: tuple[str, ...] = (
    "HUMOTION_CACHE",
    "HUMOTION_MOCAP",
    "XDG_CACHE_HOME",
    "OPENBLAS_NUM_THREADS",
    "OMP_NUM_THREADS",
    "MKL_NUM_THREADS",
)


@dataclass(frozen=True, order=True)
class Cell:
    """One leaderboard cell.

    Attributes:
        task: Task name (``BodyTrack-v2``).
        agent: Agent name (``pf-cv``, ``hold``, ``LABEL=PATH.zip``...).
        particles: Particle count; 0 for agents that take none (references,
            plain learned policies).
    """

    task: str
    agent: str
    particles: int


@dataclass(frozen=True)
class Episode:
    """The unit of work: one seeded episode of one cell, run with one agent seed.

    Attributes:
        cell: The cell.
        seed: The episode's seed (the environment's reset).
        agent_seed: The agent's seed (its filter's generator); None: the
            runner's seed (the leaderboard's ``seed``).
        window: ``(clip_id, start)`` of a declared test episode
            (:mod:`humotion_gym.envs.episodes`); None: the clip and start the
            environment draws from ``seed``.
    """

    cell: Cell
    seed: int
    agent_seed: int | None = None
    window: tuple[str, int] | None = None


#: ``(module name, fitted parameters)`` of a particle-filter agent's prior, by
#: (task, agent): what the driver fitted and the runners build filters from.
Fits = Mapping[tuple[str, str], tuple[str, Any]]
#: What a Ray worker takes of the driver's agents: the driver's ``sys.path`` and its
#: ``AGENTS`` and ``REFERENCES``, pickled (read once that path is the worker's too).
Registry = tuple[list[str], bytes]


def make_env(task: str, env_kwargs: Mapping[str, Any] | None = None) -> gym.Env:
    """A task's environment as the leaderboard runs it: test persons, every episode to its end.

    A ``library`` in ``env_kwargs`` is tracked on its ``"test"`` split: a
    validation fold's (:func:`~baselines.experiments.selection.validation_library`)
    is its held-out training persons.

    Raises:
        ValueError: If ``env_kwargs`` names a ``split``: the leaderboard's
            episodes are the test split's.
    """
    kwargs = dict(env_kwargs or {})
    if "split" in kwargs:
        raise ValueError(
            f"env_kwargs: split={kwargs['split']!r}, but the leaderboard tracks the test "
            "split (choose the data with data_dir, or a validation fold with library)"
        )
    if "episode_frames" in kwargs:  # every episode to its end: no TimeLimit before it
        kwargs.setdefault("max_episode_steps", kwargs["episode_frames"])
    return gym.make(f"humotion_gym/{task}", terminate_on_lost=False, split="test", **kwargs)


def window_options(window: tuple[str, int] | None) -> dict[str, Any] | None:
    """The reset options of a declared episode's window (None: a drawn episode)."""
    return None if window is None else {"clip_id": window[0], "start": int(window[1])}


def task_windows(task: str, env_kwargs: Mapping[str, Any] | None) -> list[tuple[str, int]]:
    """A task's declared test episodes on the run's data, as ``(clip_id, start)``.

    Raises:
        ValueError: If the data's test clips have no declared list, or the
            list does not match them (a clip missing or of another length).
    """
    env = make_env(task, env_kwargs)
    try:
        base = tracking_env(env)
        source = episodes.source_of(base.library)
        windows = episodes.declared_episodes(task, source)
        span = base.episode_frames * base.frame_skip + 1
        episodes.check_windows(windows, base.library, span=span)
        return [(w.clip_id, w.start) for w in windows]
    finally:
        env.close()


def build_agent(cell: Cell, env: gym.Env, seed: int, fits: Fits | None = None) -> Any:
    """A cell's agent, seeded with ``seed``: a particle filter from its fit in ``fits``.

    Without the cell's fit (from :func:`prepare_cells`), :func:`baselines.agents.make`
    builds the agent (reading or writing the on-disk prior cache).
    """
    fit = (fits or {}).get((cell.task, cell.agent))
    n = max(cell.particles, 1)
    if fit is None:
        return make(cell.agent, env, n_particles=n, seed=seed)
    module_name, fitted = fit
    spec = AGENTS[cell.agent]
    module = importlib.import_module(module_name)
    return filter_agent(spec, env, module, fitted, n, seed, "mean", cell.agent)


def run_cell_episode(
    task: str,
    agent: str,
    particles: int,
    episode_seed: int,
    first_seed: int,
    env_kwargs: Mapping[str, Any] | None = None,
    on_frame: Callable[[NDArray[np.uint8], dict[str, Any]], None] | None = None,
    window: tuple[str, int] | None = None,
) -> EpisodeResult:
    """One leaderboard episode on its own: the numbers the leaderboard recorded for it.

    Episodes do not depend on each other, so this reproduces an episode of a
    saved leaderboard (for a video, say) without running its cell's others.
    ``first_seed`` is the agent's seed: the episode's ``agent_seed``, else the
    leaderboard's seed; ``on_frame`` is called with each rendered frame and its
    info (``env_kwargs`` must then set ``render_mode``); ``window`` is a declared
    episode's ``(clip_id, start)``.
    """
    env = make_env(task, env_kwargs)
    try:
        built = build_agent(Cell(task, agent, particles), env, first_seed)
        with single_threaded_blas():
            return run_episode(built, env, episode_seed, window_options(window), on_frame=on_frame)
    finally:
        env.close()


class EpisodeRunner:
    """Runs episodes, keeping each cell's environment and agent between them.

    One per process: the in-process engine's, or one per Ray actor. ``seed``
    seeds the agents of episodes that name none; ``fits`` are the driver's
    fitted priors; ``cached_cells`` agents are kept, one per (cell, agent seed).
    """

    def __init__(
        self,
        seed: int,
        env_kwargs: Mapping[str, Any] | None = None,
        fits: Fits | None = None,
        cached_cells: int = CACHED_CELLS,
    ) -> None:
        self.seed = int(seed)
        self.env_kwargs = dict(env_kwargs or {})
        self.fits = dict(fits or {})
        self.cached_cells = int(cached_cells)
        self._envs: dict[str, gym.Env] = {}
        self._agents: OrderedDict[tuple[Cell, int], Any] = OrderedDict()

    def _env(self, task: str) -> gym.Env:
        if task not in self._envs:
            self._envs[task] = make_env(task, self.env_kwargs)
        return self._envs[task]

    def _agent(self, cell: Cell, agent_seed: int) -> Any:
        key = (cell, agent_seed)
        if key in self._agents:
            self._agents.move_to_end(key)
            return self._agents[key]
        agent = build_agent(cell, self._env(cell.task), agent_seed, self.fits)
        warm_up(agent, self._env(cell.task), agent_seed)
        self._agents[key] = agent
        while len(self._agents) > self.cached_cells:
            self._agents.popitem(last=False)
        return agent

    def run(self, episode: Episode) -> dict[str, Any]:
        """Run one episode; its record (``result``, or ``error`` if it raised)."""
        cell = episode.cell
        agent_seed = self.seed if episode.agent_seed is None else int(episode.agent_seed)
        record = _record(episode, agent_seed)
        t0 = time.perf_counter()
        try:
            agent = self._agent(cell, agent_seed)
            with single_threaded_blas():
                result = run_episode(
                    agent, self._env(cell.task), episode.seed, window_options(episode.window)
                )
            record["result"] = result.to_dict()
        except Exception as exc:  # an agent that raises is an error row, not a crash
            record["error"] = f"{type(exc).__name__}: {exc}"
            record["traceback"] = traceback.format_exc()
            self._agents.pop((cell, agent_seed), None)  # a half-run agent is not reused
        record["wall_s"] = time.perf_counter() - t0
        return record

    def close(self) -> None:
        """Close the environments."""
        for env in self._envs.values():
            env.close()
        self._envs.clear()
        self._agents.clear()


def prepare_cells(
    cells: Sequence[Cell],
    seed: int,
    env_kwargs: Mapping[str, Any] | None = None,
    progress: bool = True,
) -> tuple[dict[tuple[str, str], tuple[str, Any]], dict[tuple[str, str], tuple[str, str]]]:
    """Build every (task, agent) once in the driver: fit its prior, find what cannot run.

    Fits go to the on-disk prior cache as well (:func:`baselines.agents.fit_prior`),
    where hybrids' runners read them.

    Returns:
        ``(fits, problems)`` by (task, agent): each particle-filter agent's
        fitted prior; ``("skipped", reason)`` where the agent does not cover the
        task (:class:`~baselines.agents.TaskNotSupported`), ``("error", reason)``
        where building it failed otherwise.
    """
    first: dict[tuple[str, str], Cell] = {}
    for cell in cells:
        first.setdefault((cell.task, cell.agent), cell)
    fits: dict[tuple[str, str], tuple[str, Any]] = {}
    problems: dict[tuple[str, str], tuple[str, str]] = {}
    runner = EpisodeRunner(seed, env_kwargs)  # its environments: one per task
    bar = tqdm(
        first.items(), desc="agents", unit="agent", disable=not progress, leave=False,
        file=sys.stderr,
    )  # fmt: skip
    try:
        for (task, name), cell in bar:
            bar.set_postfix_str(f"{name} on {task}")
            env = runner._env(task)
            try:
                # a fit prints what it fits and its progress: on lines of their own
                with tqdm.external_write_mode(file=sys.stderr):
                    agent = build_agent(cell, env, seed)
            except TaskNotSupported as exc:  # the agent does not cover this task
                problems[(task, name)] = ("skipped", str(exc))
                continue
            except KeyError:  # an unknown agent name is the caller's mistake
                raise
            except Exception as exc:  # a fit or a load that failed: an error row
                problems[(task, name)] = (
                    "error",
                    f"building it failed: {type(exc).__name__}: {exc}",
                )
                continue
            if type(agent) is ParticleFilterAgent:
                fits[(task, name)] = (agent.prior.__name__, agent.fitted)
    finally:
        runner.close()
    return fits, problems


class InProcessEngine:
    """Runs episodes one after another in this process (no Ray needed)."""

    workers = 1

    def __init__(self, seed: int, env_kwargs: Mapping[str, Any] | None) -> None:
        self.runner = EpisodeRunner(seed, env_kwargs)

    def start(self, fits: Fits, agents: Collection[str] = ()) -> None:
        """Hand the runner the driver's fitted priors (``agents``: the Ray engine's alone)."""
        del agents
        self.runner.fits = dict(fits)

    def run(self, episodes: Iterable[Episode], on_record: Callable[[dict[str, Any]], None]) -> None:
        """Run the episodes, handing each record to ``on_record`` as it finishes."""
        for episode in episodes:
            on_record(self.runner.run(episode))

    def close(self) -> None:
        """Close the runner's environments."""
        self.runner.close()


class _RayWorker:
    """A Ray actor's body: an :class:`EpisodeRunner` with one BLAS and OpenCV thread."""

    def __init__(self, seed: int, env_kwargs: Mapping[str, Any], tasks: Sequence[str]) -> None:
        limit_blas_threads()
        cv2.setNumThreads(1)  # one CPU per actor: OpenCV's pool would take every core
        self.version = package_version()
        self.runner = EpisodeRunner(seed, env_kwargs)
        for task in tasks:  # load the clips while the driver fits
            try:
                self.runner._env(task)
            except Exception:  # the episode that needs it reports the error
                pass

    def start(self, fits: Fits, registry: Registry) -> tuple[str, int]:
        """Take the fitted priors and the driver's registered agents; this worker's version and pid.

        Agents registered in the driver (``register_agent``, ``register_reference``)
        are built here by the same names, their modules found on the driver's ``sys.path``.
        """
        paths, blob = registry
        sys.path.extend(p for p in paths if p not in sys.path)
        agents, references = pickle.loads(blob)  # noqa: S301  (the driver's own objects)
        AGENTS.update(agents)
        REFERENCES.update(references)
        self.runner.fits = dict(fits)
        return self.version, os.getpid()

    def run(self, episode: Episode) -> dict[str, Any]:
        """Run one episode (see :meth:`EpisodeRunner.run`)."""
        return self.runner.run(episode)


def _import_ray() -> Any:
    try:
        import ray
    except ModuleNotFoundError as exc:
        raise ModuleNotFoundError(
            "the ray engine needs Ray; install the distributed extra: "
            "pip install -e '.[distributed]'",
            name="ray",
        ) from exc
    return ray


class _Schedule:
    """Which episode a free worker runs next: preferably one of a cell it has built.

    A worker keeps to its cell while it has episodes left, then takes a cell no
    worker has started, then helps on the one with the most left, so that each
    cell is built by as few workers as possible; the order changes no number.
    """

    def __init__(self, episodes: Iterable[Episode]) -> None:
        self.left: OrderedDict[Cell, deque[Episode]] = OrderedDict()
        for episode in episodes:
            self.left.setdefault(episode.cell, deque()).append(episode)
        self.started: set[Cell] = set()
        self.last: dict[int, Cell] = {}

    def __bool__(self) -> bool:
        return bool(self.left)

    def next(self, slot: int) -> Episode | None:
        if not self.left:
            return None
        cell = self.last.get(slot)
        if cell not in self.left:
            fresh = [c for c in self.left if c not in self.started]
            cell = fresh[0] if fresh else max(self.left, key=lambda c: len(self.left[c]))
        queue = self.left[cell]
        episode = queue.popleft()
        if not queue:
            del self.left[cell]
        self.started.add(cell)
        self.last[slot] = cell
        return episode


def _keeping_sigterm(call: Callable[[], Any]) -> None:
    """Run ``call`` (``ray.init``, ``ray.shutdown``), then give SIGTERM back to the program.

    Both replace the SIGTERM handler, so the program's own (the console scripts'
    :class:`~humotion_gym.cli.Terminated`: save the run, exit 143) would never run.
    """
    main = threading.current_thread() is threading.main_thread()
    previous = signal.getsignal(signal.SIGTERM) if main else None
    try:
        call()
    finally:
        if callable(previous):
            signal.signal(signal.SIGTERM, previous)


class _Call(NamedTuple):
    """An episode sent to a Ray worker and not yet collected."""

    slot: int  # the worker's place in RayEngine.actors
    episode: Episode
    actor: Any
    deaths: int  # how often a worker died as it ran this episode
    order: int  # when it was sent: a worker runs its calls in this order


class RayEngine:
    """Runs episodes on Ray actors, one :class:`EpisodeRunner` each.

    The actors start (a process each, importing the package) as soon as the
    engine is made, while the driver fits the priors; :meth:`start` hands
    them the fits, through the object store.

    Args:
        seed: Every agent's seed.
        env_kwargs: The environments' settings (paths in them must exist on
            every node).
        workers: Actors to start (one CPU each); on a local Ray also the CPUs
            it gets. None: every CPU of the cluster (of this machine when Ray
            is started here).
        address: A running cluster to join (``ray://...`` or ``HOST:PORT``);
            else ``RAY_ADDRESS`` if set, else a local Ray is started here.
            A Ray already initialised in this process is used as it is.
        tasks: The run's tasks: each actor makes their environments (loads
            the clips) as it starts.
        jobs: The episodes to run: no more actors start than there are.

    Raises:
        ModuleNotFoundError: If Ray is not installed.
        NoRayCluster: If nothing answers at ``address``.
        BadWorkers: If the cluster of ``address`` has fewer CPUs than
            ``workers`` (the actors beyond would wait for ever).
    """

    def __init__(
        self,
        seed: int,
        env_kwargs: Mapping[str, Any] | None,
        workers: int | None = None,
        address: str | None = None,
        tasks: Sequence[str] = (),
        jobs: int | None = None,
    ) -> None:
        ray = _import_ray()
        self.ray = ray
        self.started = False
        self.actors: list[Any] = []
        try:  # an interrupted start stops the Ray it started
            joined = self._connect(workers, address, jobs)
            cpus = max(1, int(ray.cluster_resources().get("CPU", 1)))
            if joined and workers is not None and workers > cpus:
                raise BadWorkers(
                    f"{workers} workers of one CPU each, but the Ray cluster has {cpus} CPUs: "
                    f"the others would wait for ever; give {cpus} or fewer"
                )
            self.workers = _at_most(int(workers or cpus), jobs)
            self._actor = ray.remote(num_cpus=1)(_RayWorker)
            self._args = (int(seed), dict(env_kwargs or {}), list(dict.fromkeys(tasks)))
            # What start() gave every worker, for one that replaces a dead worker.
            self._started_with: tuple[Any, Any] | None = None
            self.actors = [self._actor.remote(*self._args) for _ in range(self.workers)]
        except BaseException:
            self.close()
            raise

    def _connect(self, workers: int | None, address: str | None, jobs: int | None) -> bool:
        """Join the cluster at ``address`` (or ``RAY_ADDRESS``), else start a Ray of our own.

        Returns:
            Whether the Ray is one this run did not size (joined, or already up).
        """
        ray = self.ray
        if ray.is_initialized():
            return True
        env_vars = {k: os.environ[k] for k in WORKER_ENV_VARS if os.environ.get(k)}
        common: dict[str, Any] = {
            "runtime_env": {"env_vars": env_vars} if env_vars else None,
            "logging_level": logging.WARNING,
            "log_to_driver": True,
        }
        address = address or os.environ.get("RAY_ADDRESS") or None
        quiet_token_note()
        # Set first: whatever an interrupted init leaves running is ours to stop.
        if address:
            check_ray_address(address)
            self.started = True
            _keeping_sigterm(lambda: ray.init(address=address, **common))
            return True
        # "local": a Ray of this run's own, even beside a `ray start` cluster
        cpus = _at_most(workers or os.cpu_count() or 1, jobs)
        self.started = True
        _keeping_sigterm(
            lambda: ray.init(address="local", num_cpus=cpus, include_dashboard=False, **common)
        )
        return False

    def start(self, fits: Fits, agents: Collection[str] = ()) -> None:
        """Put the fits in the object store once and hand them to every actor.

        The actors take this process's registrations of the run's ``agents``
        too (:meth:`_RayWorker.start`): one registered here runs there by its
        name (a hybrid ``pf-NAME+POLICY`` takes ``pf-NAME``'s).

        Raises:
            WorkerStartError: If a registration cannot be pickled, a worker
                cannot take it (a class it cannot import) or runs another
                version of the package.
        """
        fits_ref = self.ray.put(dict(fits))
        names = set(agents) | {a.split("+", 1)[0] for a in agents}
        try:
            # pickled here (Ray's cloudpickle: a class of the driver's __main__ by
            # value), read in the worker once the driver's import path is its own
            blob = self.ray.cloudpickle.dumps(
                (
                    {k: v for k, v in AGENTS.items() if k in names},
                    {k: v for k, v in REFERENCES.items() if k in names},
                )
            )
        except Exception as exc:  # a registered object that does not pickle (a lock, say)
            raise WorkerStartError(
                f"the run's registered agents cannot be sent to the workers "
                f"({type(exc).__name__}: {exc})"
            ) from None
        registry = self.ray.put(([os.path.abspath(p) for p in sys.path], blob))
        mine = package_version()
        try:
            started = self.ray.get([a.start.remote(fits_ref, registry) for a in self.actors])
        except self.ray.exceptions.RayTaskError as exc:  # raised in the worker's start
            cause: BaseException = exc
            for _ in range(4):  # Ray wraps the worker's error (RaySystemError.client_exc)
                inner = getattr(cause, "cause", None) or getattr(cause, "client_exc", None)
                if not isinstance(inner, BaseException) or inner is cause:
                    break
                cause = inner
            # a registered class the workers cannot import fails to unpickle there
            unpickled = isinstance(cause, (ImportError, AttributeError))
            hint = (
                "; define the agents you register in a module the workers can import"
                if unpickled or "No module named" in str(cause)
                else ""
            )
            raise WorkerStartError(
                f"a Ray worker could not start ({type(cause).__name__}: "
                f"{(str(cause).strip().splitlines() or [''])[0][:200]}){hint}"
            ) from None
        for version, pid in started:
            if version != mine:
                raise WorkerStartError(
                    f"a Ray worker (pid {pid}) runs humotion_gym {version}, this driver "
                    f"{mine}: install the same version on every node"
                )
        self._started_with = (fits_ref, registry)

    def run(self, episodes: Iterable[Episode], on_record: Callable[[dict[str, Any]], None]) -> None:
        """Run the episodes, handing each record to ``on_record`` as it finishes.

        Records come in the order episodes finish, not the order given. A worker
        that dies (a node lost, a process killed) is replaced, and the episodes
        it held run again on the replacement. Ray fails every call queued on a
        dead worker and runs a worker's calls in the order they were sent, so
        the earliest was the one it ran; an episode whose worker died as it ran
        it, twice, is lost (an error record).
        """
        ray = self.ray
        schedule = _Schedule(episodes)
        pending: dict[Any, _Call] = {}  # by Ray's reference to the call's result
        sent = itertools.count()

        def send(slot: int, episode: Episode, deaths: int) -> None:
            actor = self.actors[slot]
            pending[actor.run.remote(episode)] = _Call(slot, episode, actor, deaths, next(sent))

        def submit(slot: int) -> None:
            episode = schedule.next(slot)
            if episode is not None:
                send(slot, episode, 0)

        for _ in range(QUEUE_DEPTH):
            for slot in range(len(self.actors)):
                submit(slot)
        while pending:
            (ref,), _ = ray.wait(list(pending), num_returns=1)
            call = pending.pop(ref)
            slot = call.slot
            try:
                record = ray.get(ref)
            except ray.exceptions.RayActorError as exc:  # the worker died
                on_dead = [r for r, c in pending.items() if c.actor is call.actor]
                held = sorted([call, *(pending.pop(r) for r in on_dead)], key=lambda c: c.order)
                self._replace(slot)
                ran, queued = held[0], held[1:]
                for waiting in queued:  # they never started: not their fault
                    send(slot, waiting.episode, waiting.deaths)
                if ran.deaths == 0:  # perhaps a node lost: once more, after the others
                    send(slot, ran.episode, 1)
                    continue
                record = _lost(ran.episode, f"the Ray worker died as it ran it, twice: {exc}")
            except ray.exceptions.RayError as exc:
                record = _lost(call.episode, f"{type(exc).__name__}: {exc}")
            on_record(record)
            submit(slot)

    def _replace(self, slot: int) -> None:
        """A new worker in ``slot``, started as :meth:`start` started the others."""
        self.actors[slot] = self._actor.remote(*self._args)
        if self._started_with is not None:
            self.actors[slot].start.remote(*self._started_with)

    def close(self) -> None:
        """Stop the actors, and Ray if this engine started it."""
        for actor in self.actors:
            self.ray.kill(actor)
        self.actors = []
        if self.started:
            self.started = False
            _keeping_sigterm(self.ray.shutdown)


def _at_most(wanted: int, jobs: int | None) -> int:
    """``wanted`` workers, no more than ``jobs`` episodes to run (None: no bound)."""
    return min(wanted, jobs) if jobs else wanted


def _record(episode: Episode, agent_seed: int | None) -> dict[str, Any]:
    """The head of an episode's record: its cell, its seed and its agent seed."""
    cell = episode.cell
    return {
        "task": cell.task, "agent": cell.agent, "particles": cell.particles,
        "seed": episode.seed, "agent_seed": agent_seed,
    }  # fmt: skip


def _lost(episode: Episode, why: str) -> dict[str, Any]:
    """The record of an episode its Ray worker lost (it died or Ray failed)."""
    return {**_record(episode, episode.agent_seed), "error": why, "traceback": "", "wall_s": 0.0}


def make_engine(
    name: str,
    seed: int,
    env_kwargs: Mapping[str, Any] | None,
    workers: int | None = None,
    address: str | None = None,
    tasks: Sequence[str] = (),
    jobs: int | None = None,
) -> InProcessEngine | RayEngine:
    """An engine by name (:data:`ENGINES`); call its ``start(fits)`` before ``run``.

    Raises:
        ValueError: For an unknown name, or ``workers``/``address`` given to
            the in-process engine.
    """
    if name == "inprocess":
        if address is not None or (workers is not None and workers != 1):
            raise ValueError("workers, address: the inprocess engine runs one worker, here")
        return InProcessEngine(seed, env_kwargs)
    if name == "ray":
        return RayEngine(seed, env_kwargs, workers, address, tasks, jobs)
    raise ValueError(f"engine: expected one of {list(ENGINES)}, got {name!r}")


class BadWorkers(ValueError):
    """More workers than the Ray cluster has CPUs for."""


class WorkerStartError(RuntimeError):
    """A Ray worker could not start the run: another version, or an agent it cannot take."""


def resolve_env_kwargs(env_kwargs: Mapping[str, Any] | None) -> dict[str, Any]:
    """The env settings with ``data_dir`` a list of absolute folders (workers run elsewhere).

    One folder given alone becomes a list of one, as the command line gives it,
    so a run saved by either resumes from the other.
    """
    kwargs = dict(env_kwargs or {})
    data_dir = kwargs.get("data_dir")
    if isinstance(data_dir, (str, Path)):
        kwargs["data_dir"] = [str(Path(data_dir).resolve())]
    elif isinstance(data_dir, (list, tuple)):
        kwargs["data_dir"] = [str(Path(d).resolve()) for d in data_dir]
    return kwargs
