"""The leaderboard: agents x tasks x particle counts x seeded episodes.

Every cell runs the same seeded episodes (``seed``, ``seed + 1``, ...) through
:func:`baselines.leaderboard.evaluation.run_episode`, so agents see the same
clips, start frames and scenes; the ``hold`` reference runs on every task, the
floor every row is read against (:mod:`baselines.leaderboard.tables`). With
``agent_seeds`` K above 1 every cell runs its episodes with the agent seeds
``seed`` ... ``seed + K - 1``.

Episodes are run in-process or on Ray by :mod:`baselines.leaderboard.engine`,
with the same numbers either way. With a results folder
(:mod:`baselines.leaderboard.results`) each episode is saved as it finishes,
an interrupted run resumes where it stopped, and the run ends with
``results.json``, ``table.md`` and the report (:mod:`baselines.leaderboard.report`).
"""

from __future__ import annotations

import hashlib
import shlex
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from tqdm.auto import tqdm

from baselines import MAX_PARTICLES
from baselines.agents import uses_particles
from baselines.agents.learned import policy_file
from baselines.leaderboard.engine import (
    ENGINES,
    Cell,
    Episode,
    make_engine,
    prepare_cells,
    resolve_env_kwargs,
    task_windows,
)
from baselines.leaderboard.evaluation import EpisodeResult, summarize
from baselines.leaderboard.results import (
    SCHEMA_VERSION,
    ResultsFolder,
    ResumeError,
    data_folders,
    source_commit,
    write_results,
)
from baselines.leaderboard.rows import agent_label
from baselines.leaderboard.tables import FLOOR
from humotion_gym.checks import is_count
from humotion_gym.envs.tasks import TASKS, VIEW_VARIANTS
from humotion_gym.mocap.library import package_version


def grid_cells(
    tasks: Sequence[str], agents: Sequence[str], particles: Sequence[int]
) -> list[tuple[str, str, int]]:
    """The run's ``(task, agent, particles)`` cells: ``hold`` first on every task.

    References and learned policies take no particles (one cell per task, 0);
    a task, agent or count given twice runs once.
    """
    names = [FLOOR] + [a for a in agents if a != FLOOR]
    cells: list[tuple[str, str, int]] = []
    for task in tasks:
        for name in names:
            counts = list(particles) if uses_particles(name) else [0]
            cells.extend((task, name, n) for n in counts)
    return list(dict.fromkeys(cells))


def run_leaderboard(
    tasks: Sequence[str],
    agents: Sequence[str],
    particles: Sequence[int],
    episodes: int = 20,
    seed: int = 0,
    env_kwargs: dict[str, Any] | None = None,
    progress: bool = True,
    *,
    engine: str = "inprocess",
    workers: int | None = None,
    address: str | None = None,
    out: str | Path | None = None,
    resume: bool = False,
    command: str | None = None,
    report: bool = True,
    videos: bool = False,
    agent_seeds: int = 1,
    declared: bool = False,
) -> list[dict[str, Any]]:
    """Run every (task, agent, particle count) cell, and ``hold`` on every task.

    Reference agents (``hold``, ``random``) and learned policies (``bc``,
    ``ppo``, ``LABEL=PATH.zip``) run once per task with ``particles`` 0. Every
    cell runs episodes ``seed`` ... ``seed + episodes - 1``.

    Args:
        tasks: Task names.
        agents: Agent names (``hold`` runs whether or not it is named).
        particles: Particle counts of the particle filters.
        episodes: Episodes per cell.
        seed: The first episode's seed, and the first agent seed.
        env_kwargs: Environment settings (``data_dir``, ``noise``...).
        progress: Show progress bars (agents prepared, episodes, time left).
        engine: ``"inprocess"`` or ``"ray"`` (:data:`baselines.leaderboard.engine.ENGINES`).
        workers: Ray workers (None: every CPU of the cluster).
        address: A Ray cluster to join (else ``RAY_ADDRESS``, else a local Ray).
        out: A results folder: every finished episode is appended to its
            ``episodes.jsonl`` as it finishes, and ``results.json``,
            ``table.md`` and the report are written at the end.
        resume: Continue the run saved in ``out``, skipping finished episodes.
        command: The command line that ran this (kept in ``results.json``).
        report: With ``out``, also write the report (figures, ``index.html``).
        videos: With ``out`` and ``report``, also the videos of each cell's
            best, median and worst episode (each re-run).
        agent_seeds: Agent seeds per cell (``seed``, ``seed + 1``...) on the same episodes.
        declared: Run each task's declared test episodes
            (:mod:`humotion_gym.envs.episodes`: fixed windows over every test
            clip, the same for every agent) instead of ``episodes`` drawn
            ones; episode ``k`` of a task's list has seed ``seed + k`` (its
            scene's randomness), and the intervals resample clips.

    Returns:
        One dict per cell: ``task``, ``agent``, ``particles`` and either
        ``summary`` and ``episodes`` (by seed; where several agent seeds, by
        agent seed then seed, with ``agent_seed``), or ``skipped`` (why), or
        ``error`` (the agent could not be built or an episode raised: what
        happened; with ``failed_seeds``).

    Raises:
        ValueError: If a task is not a registered task id, ``episodes``,
            ``agent_seeds`` or a particle count < 1,
            ``videos`` with several agent seeds, the engine is unknown or two
            agents would share a table label.
        ResumeError: If a resumed run's settings, agent seeds or a learned
            agent's policy file differ from the saved run's.
        FileExistsError: If ``out`` holds a run and ``resume`` is False.
        FileNotFoundError: If ``resume`` is True and ``out`` holds no run.
    """
    check_grid(tasks, agents, particles, env_kwargs)
    _check_run(seed, episodes, particles, engine, resume, out, agent_seeds, videos)
    check_labels(agents)
    kwargs = resolve_env_kwargs(env_kwargs)
    cells = [Cell(*c) for c in grid_cells(tasks, agents, particles)]
    windows = _windows(tasks, kwargs, seed, episodes, declared)
    agent_seed_list = list(range(seed, seed + agent_seeds))
    folder, policies = (ResultsFolder(out) if out is not None else None), policy_hashes(agents)
    done = _saved(
        folder, _settings(seed, kwargs, declared), resume, seed, agent_seed_list, policies
    )
    left = _left(cells, windows, agent_seed_list, done)
    runner = make_engine(engine, seed, kwargs, workers, address, tasks, len(left)) if left else None
    problems, failures = _run_left(runner, cells, left, done, folder, seed, kwargs, progress)
    rows = _rows(cells, windows, agent_seed_list, done, problems, failures, seed, declared)
    if folder is not None:
        config = {
            "tasks": list(tasks), "agents": list(agents), "particles": list(particles),
            "episodes": None if declared else episodes, "seed": seed, "env_kwargs": kwargs,
            "engine": engine, "workers": workers, "address": address,
            **({"agent_seeds": agent_seeds} if agent_seeds != 1 else {}),
            **({"policy_sha256": policies} if policies else {}),
            **({"declared": True} if declared else {}),
        }  # fmt: skip
        write_results(rows, folder.folder, config, command, report, videos, progress)
    return rows


def _run_left(
    runner: Any,
    cells: Sequence[Cell],
    left: list[Episode],
    done: dict[_Key, dict[str, Any]],
    folder: ResultsFolder | None,
    seed: int,
    kwargs: dict[str, Any],
    progress: bool,
) -> tuple[dict[tuple[str, str], tuple[str, str]], dict[Cell, list[dict[str, Any]]]]:
    """Fit the priors, then run the episodes left on ``runner`` (closed at the end).

    Returns the cells that could not run (by task and agent: why) and the
    failed episodes' records; finished ones go into ``done``.
    """
    failures: dict[Cell, list[dict[str, Any]]] = {}
    try:
        fits, problems = prepare_cells(cells, seed, kwargs, progress)
        todo = [e for e in left if (e.cell.task, e.cell.agent) not in problems]
        if runner is not None and todo:
            runner.start(fits, sorted({c.agent for c in cells}))
            _run_episodes(runner, todo, len(done), done, failures, folder, progress, seed)
    finally:
        if runner is not None:
            runner.close()
    return problems, failures


def check_grid(
    tasks: Sequence[str],
    agents: Sequence[str],
    particles: Sequence[int],
    env_kwargs: Mapping[str, Any] | None,
) -> None:
    """Refuse a grid that is not lists of names and counts, or that would drop an agent."""
    for name, values in (("tasks", tasks), ("agents", agents), ("particles", particles)):
        if isinstance(values, (str, bytes)) or not isinstance(values, Sequence):
            raise TypeError(f"{name}: expected a list, got {values!r}")
    if not tasks or not agents:
        raise ValueError(f"{'tasks' if not tasks else 'agents'}: expected at least one")
    known = {*TASKS, *VIEW_VARIANTS}  # before any folder or environment is made
    for i, task in enumerate(tasks):
        if not isinstance(task, str) or task not in known:
            raise ValueError(
                f"tasks[{i}]: unknown task {task!r}; the tasks are {', '.join(sorted(known))}"
            )
    takes = [a for a in agents if uses_particles(a)]
    if takes and not particles:
        verb = "takes" if len(takes) == 1 else "take"
        raise ValueError(f"particles: empty, but {', '.join(takes)} {verb} particles")
    if env_kwargs is not None and not isinstance(env_kwargs, Mapping):
        raise TypeError(f"env_kwargs: expected a dict of environment settings, got {env_kwargs!r}")
    if "terminate_on_lost" in (env_kwargs or {}):
        raise ValueError(
            "env_kwargs: terminate_on_lost is the leaderboard's own (False: every episode runs "
            "its full length, so a tracker that loses track early cannot score better)"
        )


def _check_run(
    seed: int,
    episodes: int,
    particles: Sequence[int],
    engine: str,
    resume: bool,
    out: str | Path | None,
    agent_seeds: int = 1,
    videos: bool = False,
) -> None:
    """Refuse a run's arguments before any work (see :func:`run_leaderboard`)."""
    counts = {"agent_seeds": (agent_seeds, 1), "episodes": (episodes, 1), "seed": (seed, 0)}
    counts |= {f"particles[{i}]": (n, 1) for i, n in enumerate(particles)}
    for name, (value, low) in counts.items():
        if not is_count(value, low):
            raise ValueError(f"{name}: expected an integer >= {low}, got {value!r}")
    for i, n in enumerate(particles):  # as agents.make and --particles
        if n > MAX_PARTICLES:
            raise ValueError(f"particles[{i}]: expected at most {MAX_PARTICLES:,}, got {n:,}")
    if videos and agent_seeds > 1:
        raise ValueError("videos: a video replays one agent seed; run them with agent_seeds=1")
    if engine not in ENGINES:
        raise ValueError(f"engine: expected one of {list(ENGINES)}, got {engine!r}")
    if resume and out is None:
        raise ValueError("resume: needs a results folder (out)")


def check_labels(agents: Sequence[str]) -> None:
    """Refuse two agents the tables would show under one name (:func:`agent_label`)."""
    shown: dict[str, str] = {}
    for name in dict.fromkeys(agents):
        label = agent_label(name)
        if label in shown:
            raise ValueError(
                f"agents: {shown[label]} and {name} would both be shown as {label!r}; give "
                "them distinct labels (LABEL=PATH.zip)"
            )
        shown[label] = name


#: An episode record's (task, agent, particles, episode seed, agent seed).
_Key = tuple[str, str, int, int, int]


def _key(record: dict[str, Any], seed: int) -> _Key:
    """A record's key; a record without ``agent_seed`` ran with the run's ``seed``."""
    agent_seed = record.get("agent_seed")
    return (
        record["task"], record["agent"], int(record["particles"]), int(record["seed"]),
        seed if agent_seed is None else int(agent_seed),
    )  # fmt: skip


#: Per task, each episode's seed and declared window (None: drawn from the seed).
_Windows = dict[str, dict[int, tuple[str, int] | None]]


def _windows(
    tasks: Sequence[str], env_kwargs: dict[str, Any], seed: int, episodes: int, declared: bool
) -> _Windows:
    """Each task's episodes: ``episodes`` drawn ones, or its declared list."""
    if not declared:
        return {task: dict.fromkeys(range(seed, seed + episodes)) for task in tasks}
    out: _Windows = {}
    for task in tasks:
        listed = task_windows(task, env_kwargs)
        out[task] = {seed + k: window for k, window in enumerate(listed)}
    return out


def _left(
    cells: Sequence[Cell],
    windows: _Windows,
    agent_seeds: Sequence[int],
    done: dict[_Key, dict[str, Any]],
) -> list[Episode]:
    """The episodes to run: every cell's, agent seed by agent seed (one agent at a time)."""
    return [
        Episode(cell, s, a, window)
        for cell in cells
        for a in agent_seeds
        for s, window in windows[cell.task].items()
        if (cell.task, cell.agent, cell.particles, s, a) not in done
    ]


def policy_hashes(agents: Sequence[str]) -> dict[str, str]:
    """The SHA-256 of each learned agent's saved policy file, by agent name.

    A path may be trained over between two runs; the package's pretrained
    policies and files not found (the agent's making reports them) are left out.
    """
    out = {}
    for name in agents:
        path = policy_file(name)
        if path is not None and path.is_file():
            out[name] = hashlib.sha256(path.read_bytes()).hexdigest()
    return out


def _saved(
    folder: ResultsFolder | None,
    settings: dict[str, Any],
    resume: bool,
    seed: int,
    agent_seeds: Sequence[int],
    policies: dict[str, str] | None = None,
) -> dict[_Key, dict[str, Any]]:
    """Start the results folder; the finished episodes' records when resuming.

    Raises:
        ResumeError: As :meth:`ResultsFolder.start` (a policy file changed
            too), or where the saved run has agent seeds this one has not
            (their episodes would leave the table).
    """
    if folder is None:
        return {}
    done = {_key(r, seed): r for r in folder.start(settings, resume, policies)}
    for key, record in done.items():  # read now, not after every episode left has run
        try:
            EpisodeResult(**record["result"])
        except TypeError as exc:
            task, agent, particles, episode, _ = key
            raise ValueError(  # a damaged file, not other settings
                f"{folder.episodes_path}: the record of {agent} ({particles} particles) on "
                f"{task}, seed {episode}, is not an episode's result ({exc}); remove its line "
                "to run that episode again"
            ) from None
    more = sorted({k[4] for k in done} - set(agent_seeds))
    if more:
        n = max(more) - seed + 1
        raise ResumeError(
            f"{folder.folder}: the saved run has agent seeds {more} beyond this run's "
            f"{list(agent_seeds)}; resume with --agent-seeds {n} (agent_seeds={n})"
        )
    return done


def _run_episodes(
    runner: Any,
    todo: list[Episode],
    n_done: int,
    records: dict[_Key, dict[str, Any]],
    failures: dict[Cell, list[dict[str, Any]]],
    folder: ResultsFolder | None,
    progress: bool,
    seed: int,
) -> None:
    """Run the episodes with a progress bar (time left), saving each record as it comes."""
    bar = tqdm(total=len(todo), desc="episodes", unit="episode", disable=not progress)
    if n_done:
        bar.write(f"resuming: {n_done} episodes were done, {len(todo)} to run", file=sys.stderr)

    def take(record: dict[str, Any]) -> None:
        if folder is not None:
            folder.append(record)
        key = _key(record, seed)
        if "result" in record:
            records[key] = record
        else:
            failures.setdefault(Cell(*key[:3]), []).append(record)
            bar.write(
                f"error: {record['agent']} on {record['task']} ({record['particles']} "
                f"particles), episode {record['seed']}: {record['error']}",
                file=sys.stderr,
            )
        bar.set_postfix_str(f"{record['agent']} on {record['task']}", refresh=False)
        bar.update(1)

    try:
        runner.run(todo, take)
    finally:
        bar.close()


def _settings(seed: int, env_kwargs: dict[str, Any], declared: bool) -> dict[str, Any]:
    """What decides an episode's numbers besides its cell and seed (checked on resume).

    The data as absolute folders (None: the synthetic set), the code's version
    and commit (a resume after a pull would mix two codes in one row), and
    whether a seed stands for a declared window or a drawn one.
    """
    return {
        "schema_version": SCHEMA_VERSION,
        "seed": seed,
        "env_kwargs": {k: v for k, v in env_kwargs.items() if k != "data_dir"},
        "data": data_folders(env_kwargs) or None,
        "declared": declared,
        "package_version": package_version(),
        "commit": source_commit(),
    }


def _rows(
    cells: Sequence[Cell],
    windows: _Windows,
    agent_seeds: Sequence[int],
    records: dict[_Key, dict[str, Any]],
    problems: dict[tuple[str, str], tuple[str, str]],
    failures: dict[Cell, list[dict[str, Any]]],
    seed: int,
    declared: bool = False,
) -> list[dict[str, Any]]:
    """One row per cell, in the cells' order, from the episodes' records."""
    rows = []
    for cell in cells:
        row: dict[str, Any] = {"task": cell.task, "agent": cell.agent, "particles": cell.particles}
        problem = problems.get((cell.task, cell.agent))
        if problem is not None:
            row[problem[0]] = problem[1]
        elif cell in failures:
            failed = sorted(failures[cell], key=lambda r: r["seed"])
            row["error"] = f"episode {failed[0]['seed']} raised {failed[0]['error']}"
            row["failed_seeds"] = [r["seed"] for r in failed]
        else:
            episodes = []
            for a in agent_seeds:
                for s in windows[cell.task]:
                    record = records[(cell.task, cell.agent, cell.particles, s, a)]
                    done = EpisodeResult(**record["result"]).to_dict()
                    # several agent seeds: each episode says its own, after its seed
                    several = len(agent_seeds) > 1
                    episodes.append({"seed": s, "agent_seed": a, **done} if several else done)
            row["summary"] = summarize(episodes, seed=seed, by_clip=declared)
            row["episodes"] = episodes
        rows.append(row)
    return rows


def default_command(
    tasks: Sequence[str],
    agents: Sequence[str],
    particles: Sequence[int],
    episodes: int,
    seed: int,
    **flags: Any,
) -> str:
    """The ``humotion-gym leaderboard`` command line of a run (kept in ``results.json``).

    ``imports``: the ``--import`` modules, each after its own flag; every other
    flag is written as ``--name value`` (``True``: the flag alone).
    """
    words = ["humotion-gym", "leaderboard", "--tasks", *tasks, "--agents", *agents]
    words += ["--particles", *map(str, particles)]
    if not flags.get("declared"):  # the declared lists fix the episodes
        words += ["--episodes", str(episodes)]
    words += ["--seed", str(seed)]
    for module in flags.pop("imports", None) or ():  # the modules that register agents
        words += ["--import", str(module)]
    for name, value in flags.items():
        if value is None or value is False:
            continue
        flag = "--" + name.replace("_", "-")
        if value is True:
            words.append(flag)
        elif isinstance(value, (list, tuple)):
            words += [flag, *map(str, value)]
        else:
            words += [flag, str(value)]
    return shlex.join(words)
