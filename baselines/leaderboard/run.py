"""The leaderboard: agents x tasks x particle counts x seeded episodes.

Every cell runs the same seeded episodes (``seed``, ``seed + 1``, ...) through
:func:`baselines.evaluation.evaluate`, so agents see the same clips, start
frames and scenes. Cells report the mean keypoint error with a 95% bootstrap
interval, its interquartile mean, the fraction of episodes that lost track and
the milliseconds per frame.

The ``hold`` reference (the initial pose every frame) runs on every task, once
(references take no particles), whether or not it was asked for: it is the
floor every row is read against. Each row gives ``x hold``, the ratio of
``hold``'s mean error to the row's (above 1: better than doing nothing), and
how many of the paired episodes the row beats ``hold`` on;
:func:`validity_lines` says per task whether the best particle filter beats
``hold`` clearly (:data:`VALID_RATIO`).

Episodes are the unit of work, run in-process or on Ray by
:mod:`baselines.engine` with the same numbers either way. With a results
folder (:class:`ResultsFolder`) each finished episode is saved as it finishes,
an interrupted run resumes where it stopped, and the run ends with
``results.json`` (:data:`SCHEMA_VERSION`; docs/leaderboard.md), ``table.md``
and the report (:mod:`baselines.report`, where present).
"""

from __future__ import annotations

import datetime
import json
import os
import shlex
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from tqdm.auto import tqdm

from baselines.agents import REFERENCES
from baselines.engine import (
    ENGINES,
    Cell,
    Episode,
    make_engine,
    prepare_cells,
    resolve_env_kwargs,
)
from baselines.evaluation import EpisodeResult, summarize
from baselines.learned import is_learned, takes_particles

#: The reference every table shows.
FLOOR = "hold"
#: A task measures tracking when its best particle filter's mean error is at
#: least this many times lower than ``hold``'s (at the smallest particle count).
VALID_RATIO = 2.0
#: The harder reference of the whole-body tasks: the body followed, the first
#: frame's articulation held. Where a table has it, :func:`validity_lines` also
#: says how far the best motion prior is ahead of it.
FOLLOW = "pf-follow"
#: The version of ``results.json``'s layout (docs/leaderboard.md describes it);
#: raised whenever a key is renamed, removed or changes meaning.
SCHEMA_VERSION = 1
#: The files of a results folder.
EPISODES_FILE = "episodes.jsonl"
RUN_FILE = "run.json"
RESULTS_FILE = "results.json"
TABLE_FILE = "table.md"


def _cells(
    tasks: Sequence[str], agents: Sequence[str], particles: Sequence[int]
) -> list[tuple[str, str, int]]:
    names = [FLOOR] + [a for a in agents if a != FLOOR]
    cells = []
    for task in tasks:
        for name in names:
            # references and learned policies take no particles: one cell per task
            once = name in REFERENCES or (is_learned(name) and not takes_particles(name))
            counts = [0] if once else list(particles)
            cells.extend((task, name, n) for n in counts)
    return list(dict.fromkeys(cells))  # a task or count given twice runs once


class ResumeError(ValueError):
    """A results folder cannot be resumed with these settings (its episodes would not match)."""


class ResultsFolder:
    """A run's results folder, written as the run goes.

    ``run.json`` holds the settings that decide the numbers (seed, environment
    settings, package version); ``episodes.jsonl`` one engine record per
    finished episode (:mod:`baselines.engine`), appended as each finishes with
    one ``write`` of one line, so an interrupted run loses at most the
    episodes in flight; ``results.json`` and ``table.md`` are written at the
    end (:func:`write_results`).

    Args:
        folder: The folder (made if missing).
    """

    def __init__(self, folder: str | Path) -> None:
        self.folder = Path(folder)
        self.episodes_path = self.folder / EPISODES_FILE
        self.run_path = self.folder / RUN_FILE

    def start(self, settings: dict[str, Any], resume: bool) -> dict[tuple[str, str, int, int], Any]:
        """Open the folder for a run; the finished episodes' records when resuming.

        Args:
            settings: What decides the numbers; a resumed run must have the same.
            resume: Continue the run saved here (skipping its finished episodes).

        Returns:
            The finished episodes' records by (task, agent, particles, seed)
            (empty unless resuming). Failed episodes are not among them: a
            resumed run retries them.

        Raises:
            FileExistsError: If the folder holds episodes and ``resume`` is False.
            FileNotFoundError: If ``resume`` is True and it holds no run.
            ResumeError: If the saved run's settings differ from ``settings``.
        """
        if resume:
            if not self.run_path.is_file():
                raise FileNotFoundError(
                    f"{self.run_path}: no run to resume in {self.folder} "
                    "(start one without --resume)"
                )
            saved = json.loads(self.run_path.read_text())
            differ = [k for k in settings if saved.get(k) != _jsonable(settings[k])]
            if differ:
                shown = "; ".join(
                    f"{k}: saved {saved.get(k)!r}, now {settings[k]!r}" for k in differ
                )
                raise ResumeError(
                    f"{self.folder}: the saved run has other settings, so its episodes would "
                    f"not match ({shown}); resume with the same settings or use another folder"
                )
            return {_key(r): r for r in self.read() if "result" in r}
        if self.episodes_path.exists() and self.episodes_path.stat().st_size > 0:
            raise FileExistsError(
                f"{self.folder} already holds a run's episodes; pass --resume to continue it "
                "or choose another folder"
            )
        self.folder.mkdir(parents=True, exist_ok=True)
        _write_text(self.run_path, json.dumps(_jsonable(settings), indent=1) + "\n")
        self.episodes_path.write_bytes(b"")
        return {}

    def read(self) -> list[dict[str, Any]]:
        """The records saved so far; a last line cut short by an interruption is dropped.

        The file is cut back to its last whole line, so appending goes on cleanly.
        """
        if not self.episodes_path.exists():
            return []
        data = self.episodes_path.read_bytes()
        whole = data[: data.rfind(b"\n") + 1]
        if len(whole) != len(data):
            with open(self.episodes_path, "r+b") as fh:
                fh.truncate(len(whole))
        records = []
        for number, line in enumerate(whole.decode().splitlines(), 1):
            if not line.strip():
                continue
            try:
                records.append(json.loads(line))
            except json.JSONDecodeError as exc:
                raise ResumeError(
                    f"{self.episodes_path}:{number}: not a JSON record ({exc})"
                ) from None
        return records

    def append(self, record: dict[str, Any]) -> None:
        """Append one record as one line, with one ``write`` (a line is whole or absent)."""
        line = (json.dumps(record, default=_plain) + "\n").encode()
        fd = os.open(self.episodes_path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        try:
            os.write(fd, line)
        finally:
            os.close(fd)


def _key(record: dict[str, Any]) -> tuple[str, str, int, int]:
    return (record["task"], record["agent"], int(record["particles"]), int(record["seed"]))


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
) -> list[dict[str, Any]]:
    """Run every (task, agent, particle count) cell, and ``hold`` on every task.

    Reference agents (``hold``, ``random``) and learned policies (``bc``,
    ``ppo``, ``LABEL=PATH.zip``) run once per task with ``particles`` 0. Every
    cell runs episodes ``seed``, ``seed + 1``... ``seed + episodes - 1``, one
    unit of work each (:mod:`baselines.engine`); the numbers are the same on
    every engine and number of workers, only the timings differ.

    Args:
        tasks: Task names.
        agents: Agent names (``hold`` runs whether or not it is named).
        particles: Particle counts of the particle filters.
        episodes: Episodes per cell.
        seed: The first episode's seed, and every agent's.
        env_kwargs: Environment settings (``data_dir``, ``noise``...).
        progress: Show progress bars (agents prepared, episodes run with the
            time left).
        engine: ``"inprocess"`` or ``"ray"`` (:data:`baselines.engine.ENGINES`).
        workers: Ray workers (None: every CPU of the cluster).
        address: A Ray cluster to join (else ``RAY_ADDRESS``, else a local Ray).
        out: A results folder: every finished episode is appended to its
            ``episodes.jsonl`` as it finishes, and ``results.json``,
            ``table.md`` and the report are written at the end.
        resume: Continue the run saved in ``out``, skipping finished episodes.
        command: The command line that ran this, kept in ``results.json``.
        report: With ``out``, also write the report (figures, ``index.html``).
        videos: With ``out`` and ``report``, also the videos of each cell's
            best, median and worst episode (each re-run).

    Returns:
        One dict per cell: ``task``, ``agent``, ``particles`` and either
        ``summary`` and ``episodes`` (sorted by seed), or ``skipped`` (the
        agent does not cover the task: why), or ``error`` (its agent could not
        be built, or an episode raised: what happened; with ``failed_seeds``).

    Raises:
        ValueError: If ``episodes`` < 1, a particle count < 1 or the engine is
            unknown.
        ResumeError: If a resumed run's settings differ from the saved run's.
        FileExistsError: If ``out`` holds a run and ``resume`` is False.
        FileNotFoundError: If ``resume`` is True and ``out`` holds no run.
    """
    if episodes < 1:
        raise ValueError(f"episodes: expected at least 1, got {episodes}")
    if any(n < 1 for n in particles):
        raise ValueError(f"particles: expected counts >= 1, got {list(particles)}")
    if engine not in ENGINES:
        raise ValueError(f"engine: expected one of {list(ENGINES)}, got {engine!r}")
    if resume and out is None:
        raise ValueError("resume: needs a results folder (out)")
    kwargs = resolve_env_kwargs(env_kwargs)
    cells = [Cell(*c) for c in _cells(tasks, agents, particles)]
    seeds = list(range(seed, seed + episodes))
    folder = ResultsFolder(out) if out is not None else None
    settings = _settings(seed, kwargs)
    done = folder.start(settings, resume) if folder is not None else {}
    left = [
        Episode(cell, s)
        for cell in cells
        for s in seeds
        if (cell.task, cell.agent, cell.particles, s) not in done
    ]
    # the engine's workers start (Ray: a process each) while the driver fits
    runner = make_engine(engine, seed, kwargs, workers, address, tasks) if left else None
    records = dict(done)
    failures: dict[Cell, list[dict[str, Any]]] = {}
    try:
        fits, problems = prepare_cells(cells, seed, kwargs, progress)
        todo = [e for e in left if (e.cell.task, e.cell.agent) not in problems]
        if runner is not None and todo:
            runner.start(fits)
            _run_episodes(runner, todo, len(done), records, failures, folder, progress)
    finally:
        if runner is not None:
            runner.close()
    rows = _rows(cells, seeds, records, problems, failures, seed)
    if folder is not None:
        config = {
            "tasks": list(tasks), "agents": list(agents), "particles": list(particles),
            "episodes": episodes, "seed": seed, "env_kwargs": kwargs, "engine": engine,
            "workers": workers, "address": address,
        }  # fmt: skip
        write_results(rows, folder.folder, config, command, report, videos, progress)
    return rows


def _run_episodes(
    runner: Any,
    todo: list[Episode],
    n_done: int,
    records: dict[tuple[str, str, int, int], dict[str, Any]],
    failures: dict[Cell, list[dict[str, Any]]],
    folder: ResultsFolder | None,
    progress: bool,
) -> None:
    """Run the episodes with a progress bar (time left), saving each record as it comes."""
    bar = tqdm(total=len(todo), desc="episodes", unit="episode", disable=not progress)
    if n_done:
        bar.write(f"resuming: {n_done} episodes were done, {len(todo)} to run", file=sys.stderr)

    def take(record: dict[str, Any]) -> None:
        if folder is not None:
            folder.append(record)
        if "result" in record:
            records[_key(record)] = record
        else:
            failures.setdefault(Cell(*_key(record)[:3]), []).append(record)
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


def _settings(seed: int, env_kwargs: dict[str, Any]) -> dict[str, Any]:
    """What decides an episode's numbers besides its cell and seed (checked on resume)."""
    from humotion_gym.mocap.library import package_version

    settings = {
        "schema_version": SCHEMA_VERSION,
        "seed": seed,
        "env_kwargs": env_kwargs,
        "package_version": package_version(),
    }
    if "data_dir" not in env_kwargs:  # the clips come from $HUMOTION_MOCAP, else synthetic
        settings["HUMOTION_MOCAP"] = os.environ.get("HUMOTION_MOCAP") or None
    return settings


def _rows(
    cells: Sequence[Cell],
    seeds: Sequence[int],
    records: dict[tuple[str, str, int, int], dict[str, Any]],
    problems: dict[tuple[str, str], tuple[str, str]],
    failures: dict[Cell, list[dict[str, Any]]],
    seed: int,
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
            results = [
                EpisodeResult(**records[(cell.task, cell.agent, cell.particles, s)]["result"])
                for s in seeds
            ]
            row["summary"] = summarize(results, seed=seed)
            row["episodes"] = [r.to_dict() for r in results]
        rows.append(row)
    return rows


def write_results(
    rows: Sequence[dict[str, Any]],
    folder: str | Path,
    config: dict[str, Any],
    command: str | None = None,
    report: bool = True,
    videos: bool = False,
    progress: bool = True,
) -> None:
    """Write ``results.json`` and ``table.md``, then the report if :mod:`baselines.report` exists.

    The report (:func:`baselines.report.write_report`: figures, ``index.html``,
    with ``videos`` the best, median and worst episode of each cell) needs the
    ``plots`` extra; without it, or with ``report`` False, the folder holds the
    results and the table alone.

    ``results.json`` (schema :data:`SCHEMA_VERSION`, docs/leaderboard.md):
    ``schema_version``, ``kind``, ``created`` (UTC), ``package_version``,
    ``command``, ``config`` (the run's arguments), ``seed`` and ``env_kwargs``
    (as in ``config``), ``rows`` (as :func:`run_leaderboard` returns them, with
    every episode) and ``validity`` (:func:`validity_lines`).
    """
    from humotion_gym.mocap.library import package_version

    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    document = {
        "schema_version": SCHEMA_VERSION,
        "kind": "humotion_gym.leaderboard",
        "created": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "package_version": package_version(),
        "command": command,
        "config": config,
        "seed": config.get("seed", 0),
        "env_kwargs": config.get("env_kwargs", {}),
        "rows": list(rows),
        "validity": validity_lines(rows),
    }
    _write_text(out / RESULTS_FILE, json.dumps(_jsonable(document), indent=1) + "\n")
    table = markdown_table(rows) + "\n\n" + "\n".join(validity_lines(rows)) + "\n"
    _write_text(out / TABLE_FILE, table)
    if not report:
        return
    try:
        from baselines.report import write_report
    except ImportError:  # the report module is optional: the folder is complete without it
        print(
            f"{out}: no figures or index.html (baselines.report is not available)", file=sys.stderr
        )
        return
    if not any("summary" in r for r in rows):
        print(f"{out}: no figures or index.html (no cell ran)", file=sys.stderr)
        return
    try:
        write_report(
            list(rows), out, videos=videos, env_kwargs=document["env_kwargs"],
            seed=document["seed"], progress=progress,
        )  # fmt: skip
    except ModuleNotFoundError as exc:  # matplotlib (the plots extra) is optional
        print(f"{out}: no figures or index.html ({exc}; install the plots extra)", file=sys.stderr)


def default_command(
    tasks: Sequence[str],
    agents: Sequence[str],
    particles: Sequence[int],
    episodes: int,
    seed: int,
    **flags: Any,
) -> str:
    """The ``humotion-gym leaderboard`` command line of a run (kept in ``results.json``)."""
    words = ["humotion-gym", "leaderboard", "--tasks", *tasks, "--agents", *agents]
    words += ["--particles", *map(str, particles), "--episodes", str(episodes)]
    words += ["--seed", str(seed)]
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


def _write_text(path: Path, text: str) -> None:
    """Write a file whole or not at all (a temporary file renamed over it)."""
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def _jsonable(value: Any) -> Any:
    """Plain JSON values (tuples to lists, numpy scalars to numbers) for comparison and writing."""
    return json.loads(json.dumps(value, default=_plain))


def _floor_of(rows: Sequence[dict[str, Any]], task: str) -> dict[str, Any] | None:
    for r in rows:
        if r["task"] == task and r["agent"] == FLOOR and "summary" in r:
            return r
    return None


def compare_to_hold(row: dict[str, Any], hold: dict[str, Any]) -> tuple[float, int, int]:
    """``hold``'s mean error over the row's, and the paired episodes the row wins.

    Episodes are paired by seed (every cell runs the same seeds). Any other
    reference row (``pf-follow``'s) is compared the same way.

    Returns:
        ``(ratio, wins, paired)``.
    """
    ratio = hold["summary"]["mean_error_mm"] / row["summary"]["mean_error_mm"]
    held = {e["seed"]: e["mean_error_mm"] for e in hold["episodes"]}
    paired = [(e["mean_error_mm"], held[e["seed"]]) for e in row["episodes"] if e["seed"] in held]
    wins = sum(1 for mine, theirs in paired if mine < theirs)
    return float(ratio), wins, len(paired)


def markdown_table(rows: Sequence[dict[str, Any]]) -> str:
    """The leaderboard as a Markdown table, with each row's ratio to ``hold``.

    A cell that did not run shows its reason: ``skipped: ...`` (the agent does
    not cover the task) or ``ERROR: ...`` (it failed).
    """
    lines = [
        "| task | agent | particles | mean error mm (95% CI) | IQM mm | pelvis-aligned mm "
        "| x hold | beats hold | lost track | ms/frame |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        particles = f"{r['particles']:,}" if r["particles"] else "-"
        if "summary" not in r:  # a cell that did not run: its reason, in the table
            what = f"skipped: {r['skipped']}" if "skipped" in r else f"ERROR: {r.get('error')}"
            what = what.replace("|", "/").replace("\n", " ")
            lines.append(f"| {r['task']} | {r['agent']} | {particles} | {what} |  |  |  |  |  |  |")
            continue
        s = r["summary"]
        lo, hi = s["mean_error_ci"]
        hold = _floor_of(rows, r["task"])
        if hold is None or r is hold:
            ratio, wins = "1.00" if r is hold else "-", "-"
        else:
            x, won, paired = compare_to_hold(r, hold)
            ratio, wins = f"{x:.2f}", f"{won}/{paired}"
        aligned = s.get("aligned_error_mm")
        aligned_text = "-" if aligned is None else f"{aligned:.0f}"
        lines.append(
            f"| {r['task']} | {r['agent']} | {particles} | {s['mean_error_mm']:.0f} "
            f"({lo:.0f}-{hi:.0f}) | {s['iqm_error_mm']:.0f} | {aligned_text} | {ratio} | {wins} | "
            f"{round(s['lost_fraction'] * s['episodes'])}/{s['episodes']} | "
            f"{s['ms_per_frame']:.1f} |"
        )
    return "\n".join(lines)


def validity_lines(rows: Sequence[dict[str, Any]]) -> list[str]:
    """Per task: does the best particle filter beat ``hold`` by :data:`VALID_RATIO`?

    Judged at the smallest particle count run, where the papers' claims are made.
    Where :data:`FOLLOW` ran at that count too, a second line compares the best
    other filter with it: what the motion prior adds to following the body.
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
        best = min(
            (r for r in filters if r["particles"] == fewest),
            key=lambda r: r["summary"]["mean_error_mm"],
        )
        ratio, wins, paired = compare_to_hold(best, hold)
        verdict = "valid" if ratio >= VALID_RATIO else f"NOT valid (below {VALID_RATIO:g}x)"
        out.append(
            f"{task}: best filter at {fewest:,} particles is {best['agent']}, "
            f"{ratio:.2f}x better than hold in mean error "
            f"({best['summary']['mean_error_mm']:.0f} vs {hold['summary']['mean_error_mm']:.0f} "
            f"mm), better in {wins}/{paired} paired episodes: {verdict}"
        )
        at_fewest = [r for r in filters if r["particles"] == fewest]
        follow = next((r for r in at_fewest if r["agent"] == FOLLOW), None)
        priors = [r for r in at_fewest if r["agent"] != FOLLOW]
        if follow is None or not priors:
            continue
        prior = min(priors, key=lambda r: r["summary"]["mean_error_mm"])
        ratio, wins, paired = compare_to_hold(prior, follow)
        means = (
            f"{prior['summary']['mean_error_mm']:.0f} vs "
            f"{follow['summary']['mean_error_mm']:.0f} mm"
        )
        won = f"better in {wins}/{paired} paired episodes"
        if ratio > 1.0:
            out.append(
                f"{task}: against {FOLLOW} (the body followed, its first articulation held), "
                f"the best other filter at {fewest:,} particles is {prior['agent']}, "
                f"{ratio:.2f}x better in mean error ({means}), {won}"
            )
        else:
            out.append(
                f"{task}: no other filter at {fewest:,} particles beats {FOLLOW} in mean "
                f"error: the best, {prior['agent']}, {means}, {won}"
            )
    return out


def save(rows: Sequence[dict[str, Any]], path: str | Path) -> None:
    """Write the rows as JSON."""
    Path(path).write_text(json.dumps(list(rows), indent=1, default=_plain))


def _plain(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"not JSON-serialisable: {type(value).__name__}")
