"""Difficulty sweeps: the leaderboard over a grid of environment settings.

A sweep varies one setting at a time (image size, background, noise,
occluders, blur, frame skip) from the task's defaults, runs
:func:`baselines.leaderboard.run_leaderboard` at every value (so every engine
feature applies) and draws the difficulty curves: each cell's interquartile
mean error against the setting, with its 95% bootstrap interval.
One-at-a-time curves keep the cost linear in the number of values; a full
product of settings grows too fast to run on one machine.
"""

from __future__ import annotations

import inspect
import json
import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from tqdm.auto import tqdm

from baselines.experiments._plotting import save as save_figure
from baselines.leaderboard.across_tasks import normalised_scores
from baselines.leaderboard.engine import make_env
from baselines.leaderboard.evaluation import summarize
from baselines.leaderboard.results import RUN_FILE, ResumeError, _jsonable, data_folders
from baselines.leaderboard.rows import cell_label
from baselines.leaderboard.run import check_grid, run_leaderboard
from baselines.leaderboard.stats import bootstrap_ci, iqm
from baselines.leaderboard.videos import file_slug
from humotion_gym.checks import is_real
from humotion_gym.envs.pose_tracking import PoseTrackingEnv
from humotion_gym.files import json_default, read_json, write_text_atomically
from humotion_gym.render import SceneOptions

#: Sweep format version (``sweep.json``'s ``version``).
VERSION = 1
#: The file of a sweep's folder holding what decides its numbers
#: (:func:`sweep_settings`), written before the first point runs: a resumed
#: sweep must be the same sweep, or its points would mix two grids.
SETTINGS_FILE = "sweep-run.json"

#: Settings a sweep can vary: name -> (environment keyword(s), what it is).
SETTINGS: dict[str, str] = {
    "size": "image width and height in pixels (width=height=SIZE)",
    "background": "scene background, 'flat' or 'clutter'",
    "noise": "per-pixel Gaussian sensor noise, grey levels",
    "occluders": "bars and blobs sweeping in front of the figure",
    "blur": "Gaussian blur of every frame, pixels",
    "frame_skip": "source frames per environment step (1: every frame)",
}


def setting_kwargs(name: str, value: Any) -> dict[str, Any]:
    """The environment keyword arguments that set one setting to a value.

    The value's range is the environment's to check (:func:`check_points`).

    Raises:
        ValueError: If the setting is unknown or the value has the wrong type
            (a count, ``size``, ``occluders`` or ``frame_skip``, that is not a
            whole number: ``int`` would run another value than the one recorded).
    """
    if name not in SETTINGS:
        raise ValueError(f"setting: expected one of {', '.join(SETTINGS)}, got {name!r}")
    if name == "background":
        if value not in ("flat", "clutter"):
            raise ValueError(f"background: expected 'flat' or 'clutter', got {value!r}")
        return {"background": value}
    if not (is_real(value) and math.isfinite(value)):
        raise ValueError(f"{name}: expected a finite number, got {value!r}")
    if name in ("size", "occluders", "frame_skip"):
        if value != int(value):
            raise ValueError(f"{name}: expected a whole number, got {value!r}")
        if name == "size":
            return {"width": int(value), "height": int(value)}
        return {name: int(value)}
    return {name: float(value)}


def check_points(
    tasks: Sequence[str], grid: Mapping[str, Sequence[Any]], env_kwargs: Mapping[str, Any]
) -> None:
    """Refuse every value of the grid that a task's environment would refuse.

    Each point's environment is built (and closed) on every task, so a value
    out of the environment's range stops the sweep before its first point runs.
    The common settings are built first, so what they get wrong is not
    blamed on a point.

    Raises:
        ValueError: Naming the setting, its value and what the environment said
            (or what the environment said of ``env_kwargs``).
    """
    for task in tasks:
        make_env(task, env_kwargs).close()
    for name, values in grid.items():
        for value in values:
            settings = {**env_kwargs, **setting_kwargs(name, value)}
            for task in tasks:
                try:
                    make_env(task, settings).close()
                except ValueError as exc:
                    raise ValueError(f"grid: {name}={value!r} on {task}: {exc}") from exc


def run_sweep(
    tasks: Sequence[str],
    agents: Sequence[str],
    particles: Sequence[int],
    grid: Mapping[str, Sequence[Any]],
    episodes: int = 5,
    seed: int = 0,
    env_kwargs: Mapping[str, Any] | None = None,
    progress: bool = True,
    engine_options: Mapping[str, Any] | None = None,
    out: str | Path | None = None,
    resume: bool = False,
    setting_name: Callable[[str], str] = str,
) -> dict[str, Any]:
    """Run the leaderboard at every value of every setting of the grid.

    Args:
        tasks: Task names.
        agents: Agent names (``hold`` always runs, as on the leaderboard).
        particles: Particle counts of the particle filters.
        grid: Setting name (see :data:`SETTINGS`) -> its values; the other
            settings keep ``env_kwargs`` or the task's defaults.
        episodes: Seeded episodes per cell and value.
        seed: First episode seed.
        env_kwargs: Settings common to every run (``data_dir``...).
        progress: Show a progress bar over the sweep's points.
        engine_options: Keyword arguments of
            :func:`~baselines.leaderboard.run_leaderboard` that choose its
            engine (``engine="ray"``, ``workers``, ``address``); none: in-process.
        out: A folder for each point's leaderboard results (:func:`point_folder`),
            every episode kept as it finishes.
        resume: Continue the sweep saved in ``out`` (its :data:`SETTINGS_FILE`
            must hold these settings), each point where it stopped.
        setting_name: How a resume's message names a setting (the command's flag).

    Returns:
        The sweep (plain JSON, :data:`VERSION`): ``tasks``, ``agents``,
        ``particles``, ``episodes``, ``seed``, ``env_kwargs`` and ``points``,
        one per (setting, value) with its leaderboard ``rows``.

    Raises:
        ValueError: If the grid is empty, names an unknown setting or holds a
            value a task's environment refuses (:func:`check_points`).
        ResumeError: If resuming a sweep saved with other settings
            (:func:`check_resume`), or a point's saved run cannot be resumed.
        FileExistsError: If ``out`` holds a sweep and ``resume`` is False.
        FileNotFoundError: If ``resume`` is True and ``out`` holds no sweep.
    """
    points = [(name, v) for name, values in grid.items() for v in values]
    if not points:
        raise ValueError("grid: expected at least one setting with at least one value")
    base = dict(env_kwargs or {})
    check_grid(tasks, agents, particles, base)  # lists of names before tasks are built
    check_points(tasks, grid, base)  # every value checked before the first run
    folder = None if out is None else Path(out)
    if folder is not None:
        settings = sweep_settings(tasks, agents, particles, grid, episodes, seed, base)
        _start(folder, settings, resume, setting_name)
    result: dict[str, Any] = {
        "version": VERSION,
        "tasks": list(tasks),
        "agents": list(agents),
        "particles": list(particles),
        "episodes": episodes,
        "seed": seed,
        "env_kwargs": base,
        "points": [],
    }
    bar = tqdm(points, desc="sweep", disable=not progress)
    for k, (name, value) in enumerate(bar):
        bar.set_postfix_str(f"{name}={value}")
        settings = {**base, **setting_kwargs(name, value)}
        kept: dict[str, Any] = {}
        if folder is not None:
            where = point_folder(folder, k, name, value)
            resumed = resume and (where / RUN_FILE).is_file()
            kept = {"out": where, "resume": resumed, "report": False}
        rows = run_leaderboard(
            tasks, agents, particles, episodes, seed, settings, **dict(engine_options or {}),
            **kept,
        )  # fmt: skip
        result["points"].append({"setting": name, "value": value, "rows": rows})
    return result


def sweep_settings(
    tasks: Sequence[str],
    agents: Sequence[str],
    particles: Sequence[int],
    grid: Mapping[str, Sequence[Any]],
    episodes: int,
    seed: int,
    env_kwargs: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """What decides a sweep's numbers and its points' folders, as plain JSON.

    The motion capture is its absolute folders, whichever way they were named
    (``data_dir`` relative or with a trailing slash, or ``$HUMOTION_MOCAP``;
    None: the built-in synthetic set), as a leaderboard's ``run.json`` keeps
    it. The engine is left out (every engine gives the same numbers), and so
    is the code's version: each point's own ``run.json`` checks that.
    """
    kwargs = dict(env_kwargs or {})
    settings = {
        "version": VERSION, "tasks": list(tasks), "agents": list(agents),
        "particles": list(particles),
        "grid": {name: list(values) for name, values in grid.items()},
        "episodes": episodes, "seed": seed,
        "env_kwargs": {k: v for k, v in kwargs.items() if k != "data_dir"},
        "data": data_folders(kwargs) or None,
    }  # fmt: skip
    return dict(_jsonable(settings))


def check_resume(
    folder: str | Path, settings: Mapping[str, Any], name: Callable[[str], str] = str
) -> None:
    """Refuse to resume the sweep saved in ``folder`` with other settings.

    Another grid would number its points otherwise, and other agents or
    episodes would leave saved episodes out of the table.

    Args:
        folder: The sweep's folder.
        settings: The resumed sweep's :func:`sweep_settings`.
        name: How a setting is named in the message (the command gives its flag).

    Raises:
        ResumeError: Naming each setting that differs, with its saved value and
            the given one; or where the folder has points but no :data:`SETTINGS_FILE`.
        FileNotFoundError: If the folder holds no sweep.
        ValueError: If the settings file is damaged (naming it).
    """
    folder = Path(folder)
    path = folder / SETTINGS_FILE
    if not path.is_file():
        if (folder / "points").is_dir():
            raise ResumeError(
                f"{folder}: its points have no {SETTINGS_FILE}, so they cannot be matched to "
                "these settings; run the sweep afresh in another folder"
            )
        raise FileNotFoundError(f"{path}: no sweep to resume in {folder}")
    saved = read_json(path)
    if not isinstance(saved, dict):
        raise ValueError(f"{path}: not a sweep's settings (a JSON object)")
    differ = _differences(saved, settings)
    if differ:
        shown = "; ".join(
            f"{name(key)}: saved {_shown(key, before)}, now {_shown(key, now)}"
            for key, before, now in differ
        )
        raise ResumeError(
            f"{folder}: the saved sweep has other settings, so its points would not match "
            f"({shown}); resume with the same settings or use another folder"
        )


def _differences(
    saved: Mapping[str, Any], settings: Mapping[str, Any]
) -> list[tuple[str, Any, Any]]:
    """``(setting, saved value, given value)`` for each setting that differs; a grid per value."""
    out = []
    for key, now in settings.items():
        before = saved.get(key)
        if key == "grid" and isinstance(before, dict) and isinstance(now, dict):
            # a setting swept in one of them only shows as "not swept" in the other
            values = [
                (setting, before.get(setting), now.get(setting))
                for setting in dict.fromkeys([*before, *now])
                if before.get(setting) != now.get(setting)
            ]
            if not values and list(before) != list(now):  # the same grid in another order
                values = [(key, list(before), list(now))]
            out += values
        elif before != now:
            out.append((key, before, now))
    return out


def _shown(key: str, value: Any) -> str:
    """A saved or given setting as a message shows it: lists as the command line takes them."""
    if value is None:  # no data folder; a setting the grid leaves out
        if key == "data":
            return "the built-in synthetic motion"
        return "not swept" if key in SETTINGS else "none"
    if isinstance(value, list):
        return " ".join(map(str, value)) or "none"
    return str(value)


def _start(
    folder: Path, settings: dict[str, Any], resume: bool, name: Callable[[str], str]
) -> None:
    """Check a resumed sweep's settings, or keep a new one's (refused over another sweep)."""
    path = folder / SETTINGS_FILE
    if resume:
        check_resume(folder, settings, name)
        return
    if path.exists():
        raise FileExistsError(
            f"{folder} already holds a sweep ({SETTINGS_FILE}); resume it or choose another folder"
        )
    folder.mkdir(parents=True, exist_ok=True)
    write_text_atomically(path, json.dumps(settings, indent=1) + "\n")


def point_folder(folder: str | Path, index: int, name: str, value: Any) -> Path:
    """The results folder of point ``index`` (``name`` at ``value``) of the sweep in ``folder``."""
    return Path(folder) / "points" / f"{index:03d}-{file_slug(f'{name}-{value}')}"


def default_value(name: str) -> Any:
    """The environment's default of a setting (the leaderboard's difficulty)."""
    scene = SceneOptions()
    env_defaults = inspect.signature(PoseTrackingEnv.__init__).parameters
    return {
        "size": scene.width,
        "background": scene.background,
        "noise": scene.noise_sigma,
        "occluders": scene.occluders,
        "blur": scene.blur_sigma,
        "frame_skip": env_defaults["frame_skip"].default,
    }[name]


#: What a curve can show (:func:`curves`' ``metric``).
METRICS: dict[str, str] = {
    "error": "IQM keypoint error, mm (95% CI)",
    "score": "IQM of error / hold's (same episode)",
}


def curves(sweep: Mapping[str, Any], metric: str = "error") -> list[dict[str, Any]]:
    """One curve per (setting, task, cell): values, IQMs and intervals.

    Args:
        sweep: A sweep (:func:`run_sweep` or :func:`load`).
        metric: ``"error"``: the IQM of the episodes' mean keypoint errors in
            mm; ``"score"``: the IQM of each episode's error over ``hold``'s
            on the same episode (paired, so the spread of episode difficulty
            cancels; ``hold`` does not look at the frames, so its own score
            is 1 everywhere).

    Returns:
        Dicts with ``setting``, ``task``, ``cell``, ``values``, ``iqm``,
        ``low``, ``high``, ``mean_mm`` and ``lost_fraction`` (lists in the
        grid's order); cells that did not run at a value are left out there.

    Raises:
        ValueError: If the metric is unknown.
    """
    if metric not in METRICS:
        raise ValueError(f"metric: expected one of {', '.join(METRICS)}, got {metric!r}")
    seed = int(sweep.get("seed", 0))
    table: dict[tuple[str, str, str], dict[str, list[Any]]] = {}
    for point in sweep["points"]:
        scores = normalised_scores(point["rows"]) if metric == "score" else {}
        for r in point["rows"]:
            if "episodes" not in r or "skipped" in r or "error" in r:
                continue
            s = summarize(r["episodes"], seed=seed)
            if metric == "score":
                values = scores.get(cell_label(r), {}).get(r["task"])
                if values is None:  # no hold on this task: no score
                    continue
                centre, (low, high) = iqm(values), bootstrap_ci(values, iqm, seed=seed)
            else:
                centre, (low, high) = s["iqm_error_mm"], s["iqm_error_ci"]
            c = table.setdefault(
                (point["setting"], r["task"], cell_label(r)),
                {k: [] for k in ("values", "iqm", "low", "high", "mean_mm", "lost_fraction")},
            )
            c["values"].append(point["value"])
            c["iqm"].append(centre)
            c["low"].append(low)
            c["high"].append(high)
            c["mean_mm"].append(s["mean_error_mm"])
            c["lost_fraction"].append(s["lost_fraction"])
    return [
        {"setting": setting, "task": task, "cell": cell, **c}
        for (setting, task, cell), c in table.items()
    ]


def problems(sweep: Mapping[str, Any]) -> list[tuple[str, str]]:
    """The cells that did not run at a setting: ``("error" or "skipped", what and why)``."""
    out = []
    for point in sweep["points"]:
        for r in point["rows"]:
            for kind in ("error", "skipped"):
                if kind in r:
                    where = f"{point['setting']}={point['value']}"
                    out.append((kind, f"{cell_label(r)} on {r['task']} at {where}: {r[kind]}"))
    return out


def markdown(sweep: Mapping[str, Any]) -> str:
    """The curves as one Markdown table: IQM error (95% CI) per cell and value.

    Cells that did not run are listed after it, each with why.
    """
    lines = [
        "| setting | value | task | agent | IQM error mm (95% CI) | mean mm | lost track |",
        "|---|---|---|---|---|---|---|",
    ]
    for c in curves(sweep):
        for k, v in enumerate(c["values"]):
            lines.append(
                f"| {c['setting']} | {v} | {c['task']} | {c['cell']} | {c['iqm'][k]:.0f} "
                f"({c['low'][k]:.0f}-{c['high'][k]:.0f}) | {c['mean_mm'][k]:.0f} | "
                f"{c['lost_fraction'][k]:.0%} |"
            )
    missing = problems(sweep)
    if missing:
        lines += ["", "Not in the table:"] + [f"- {kind.upper()}: {what}" for kind, what in missing]
    return "\n".join(lines)


def figure(
    sweep: Mapping[str, Any],
    path: str | Path,
    title: str | None = None,
    metrics: Sequence[str] = ("error", "score"),
) -> Path:
    """Difficulty curves against each setting: one panel per (task and metric, setting).

    Numeric settings are drawn on their own scale; others (background) as
    categories. Bands are the 95% bootstrap intervals of the IQM; a dotted
    line marks the setting's default (the leaderboard's difficulty).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    by_metric = {m: curves(sweep, m) for m in metrics}
    first = by_metric[metrics[0]]
    settings = list(dict.fromkeys(c["setting"] for c in first))
    tasks = list(dict.fromkeys(c["task"] for c in first))
    panels = [(task, m) for task in tasks for m in metrics]
    fig, axes = plt.subplots(
        len(panels), len(settings), figsize=(4.8 * len(settings), 3.3 * len(panels)),
        squeeze=False,
    )  # fmt: skip
    colors: dict[str, Any] = {}
    for i, (task, metric) in enumerate(panels):
        for j, setting in enumerate(settings):
            ax = axes[i, j]
            mine = [c for c in by_metric[metric] if c["task"] == task and c["setting"] == setting]
            numeric = all(isinstance(v, (int, float)) for c in mine for v in c["values"])
            for c in mine:
                if metric == "score" and c["cell"] == "hold":
                    continue  # 1 by definition: the dashed line
                x = np.asarray(c["values"], dtype=float) if numeric else np.arange(len(c["values"]))
                color = colors.setdefault(c["cell"], f"C{len(colors) % 10}")
                ax.plot(x, c["iqm"], "o-", color=color, label=c["cell"], lw=1.5, ms=4)
                ax.fill_between(x, c["low"], c["high"], color=color, alpha=0.12, lw=0)
                if not numeric:
                    ax.set_xticks(x, [str(v) for v in c["values"]])
            default = default_value(setting)
            if numeric:
                ax.axvline(float(default), color="grey", ls=":", lw=1, label="default")
            if metric == "score":
                ax.axhline(1.0, color="grey", ls="--", lw=1, label="hold")
            ax.set(title=f"{task}: {setting}", xlabel=SETTINGS[setting], ylabel=METRICS[metric])
            ax.grid(alpha=0.3)
    legend: dict[str, Any] = {}  # one entry per cell over all panels
    for ax in axes.ravel():
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            legend.setdefault(label, handle)
    fig.legend(legend.values(), legend.keys(), loc="lower center", ncol=min(len(legend), 7),
               fontsize=8, frameon=False)  # fmt: skip
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout(rect=(0, 0.06, 1, 1))
    return save_figure(fig, path, dpi=120, layout=False)


def save(sweep: Mapping[str, Any], path: str | Path) -> Path:
    """Write the sweep as JSON."""
    path = Path(path)
    write_text_atomically(path, json.dumps(sweep, indent=1, default=json_default))
    return path


def load(path: str | Path) -> dict[str, Any]:
    """Read a sweep written by :func:`save`.

    Raises:
        ValueError: If the file is not a sweep of this version (names the file).
    """
    data = json.loads(Path(path).read_text())
    if not isinstance(data, dict) or data.get("version") != VERSION or "points" not in data:
        raise ValueError(f"{path}: not a sweep file of version {VERSION}")
    return data
