"""Where an agent's error comes from: its image likelihood against truth oracles.

Each particle-filter agent tracks the same episodes several times, once with
its own image likelihood and once with each oracle of
:mod:`baselines.diagnostics.oracle` in its place (same prior, filter,
particle count and seeds), and ``hold`` once. The differences split the
error:

* **evidence**: image error less the 2D oracle's: what a perfect 2D keypoint
  detector would remove;
* **depth**: the 2D oracle's error split along the camera ray through each
  true keypoint and across it (:func:`baselines.depth.split_along_ray`), raw
  and with the pelvises put together: what one view leaves unknown;
* **search**: the 3D oracle's error: what the prior and filter lose when the
  evidence pins every keypoint (its noise sets a floor).

Per episode it records the mean error, the pelvis-aligned error, the
along/across split (raw and aligned), the estimate's reprojection error in
pixels and, where the agent's filter has weights, the mean effective sample
size after weighting. The episodes are a task's declared test list
(:func:`baselines.leaderboard.engine.task_windows`, episode seeds ``seed``,
``seed + 1``... as the leaderboard's ``--declared``) or seeded draws, so the
image rows are the leaderboard's numbers for the same settings.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray
from tqdm.auto import tqdm

from baselines.agents import make, tracking_env
from baselines.depth import split_along_ray
from baselines.diagnostics.oracle import OracleFeed, OracleSettings, TruthOracle, with_oracle
from baselines.experiments.selection import FILTER_PREFIX, FIT_PREFIX, agent_settings
from baselines.leaderboard.engine import make_env, task_windows, window_options
from baselines.leaderboard.evaluation import run_episode
from baselines.leaderboard.tables import markdown_rows
from humotion_gym.body import KEYPOINT_INDEX, forward_kinematics
from humotion_gym.threads import single_threaded_blas

_PELVIS = KEYPOINT_INDEX["pelvis"]
#: Per-episode numbers kept in the results (means over the episode's frames).
EPISODE_FIELDS: tuple[str, ...] = (
    "error_mm", "aligned_mm", "along_abs_mm", "across_mm", "aligned_along_abs_mm",
    "aligned_across_mm", "reprojection_px", "ess",
)  # fmt: skip


class _FrameRecorder:
    """``on_step`` of the loop: each answered frame's split, reprojection and ESS."""

    def __init__(self, env: gym.Env, agent: Any) -> None:
        self.base = tracking_env(env)
        self.agent = agent
        self.scored = np.asarray(self.base.task.error_keypoint_indices, dtype=np.intp)
        self.rows: dict[str, list[float]] = {name: [] for name in EPISODE_FIELDS[2:]}

    def __call__(self, action: NDArray[Any], truth: NDArray[np.float64], info: dict) -> None:
        camera = self.base.camera  # (the frame the action answers)
        estimate = self.base.action_to_pose(action, truth)
        kp = forward_kinematics(np.stack([estimate, truth]), self.base.shape)
        est, tru = kp[0, self.scored], kp[1, self.scored]
        centre = np.asarray(camera.position, dtype=np.float64)
        along, across = split_along_ray(est, tru, centre)
        aligned = est - (kp[0, _PELVIS] - kp[1, _PELVIS])
        al_along, al_across = split_along_ray(aligned, tru, centre)
        pixels = camera.project(np.stack([est, tru]))
        rows = self.rows
        rows["along_abs_mm"].append(float(np.abs(along).mean()))
        rows["across_mm"].append(float(across.mean()))
        rows["aligned_along_abs_mm"].append(float(np.abs(al_along).mean()))
        rows["aligned_across_mm"].append(float(al_across.mean()))
        rows["reprojection_px"].append(float(np.linalg.norm(pixels[0] - pixels[1], axis=-1).mean()))
        filt = getattr(self.agent, "filter", None)
        rows["ess"].append(float(filt.ess) if filt is not None else float("nan"))


class SettingsError(ValueError):
    """A setting given to :func:`run_split` that is not one of every agent's."""


def diagnose_episode(
    agent: Any, env: gym.Env, seed: int, options: dict[str, Any] | None = None
) -> dict[str, Any]:
    """One episode of the evaluation loop with its diagnostics.

    Args:
        agent: The agent (with an oracle in it, ``env`` is an :class:`OracleFeed`).
        env: The environment (``terminate_on_lost=False``).
        seed: The episode's seed.
        options: Reset options (a declared window).

    Returns:
        ``seed``, ``clip_id``, ``start_frame``, ``lost_frame`` and the
        episode means of :data:`EPISODE_FIELDS` (``ess`` None without a filter).
    """
    recorder = _FrameRecorder(env, agent)
    result = run_episode(agent, env, seed, options, on_step=recorder)
    out: dict[str, Any] = {
        "seed": seed, "clip_id": result.clip_id, "start_frame": result.start_frame,
        "lost_frame": result.lost_frame, "error_mm": result.mean_error_mm,
        "aligned_mm": result.mean_aligned_error_mm,
    }  # fmt: skip
    for name, values in recorder.rows.items():
        mean = float(np.mean(values))
        out[name] = None if np.isnan(mean) else mean
    return out


def parse_oracle(text: str) -> OracleSettings | None:
    """A likelihood by name: ``image`` (None), ``2d``, ``2d-unlabelled``, ``3d``.

    A suffix sets the noise: ``2d:2`` (pixels), ``3d:10mm`` (mm per axis).

    Raises:
        ValueError: If the name or the noise is not one of those.
    """
    if text == "image":
        return None
    kind, colon, noise = text.partition(":")
    try:
        if colon and not noise:
            raise ValueError("a colon without a noise")
        if noise.endswith("mm"):
            return OracleSettings(kind, noise_mm=float(noise[:-2]))
        return OracleSettings(kind, noise_px=float(noise) if noise else None)
    except ValueError as exc:
        raise ValueError(
            f"likelihood {text!r}: expected image, 2d, 2d-unlabelled or 3d, optionally with "
            f"a noise such as 2d:1 (pixels) or 3d:10mm ({exc})"
        ) from exc


def _label(oracle: OracleSettings | None) -> str:
    return "image" if oracle is None else oracle.label


def _summary(episodes: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """Means over the episodes (and agent seeds) of each per-episode number."""
    out: dict[str, Any] = {"episodes": len(episodes)}
    for name in EPISODE_FIELDS:
        values = [e[name] for e in episodes if e.get(name) is not None]
        out[name] = float(np.mean(values)) if len(values) == len(episodes) else None
    out["lost_episodes"] = sum(e["lost_frame"] is not None for e in episodes)
    return out


def run_split(
    task: str,
    agents: Sequence[str],
    oracles: Sequence[OracleSettings | None],
    particles: int = 300,
    episodes: int | None = None,
    declared: bool = True,
    seed: int = 0,
    agent_seeds: int = 1,
    env_kwargs: Mapping[str, Any] | None = None,
    progress: bool = True,
    on_row: Callable[[dict[str, Any]], None] | None = None,
    settings: Mapping[str, float | str] | None = None,
    done: Sequence[Mapping[str, Any]] = (),
) -> dict[str, Any]:
    """Every agent with every likelihood on one task's episodes, and ``hold``.

    Args:
        task: A task id (``BodyTrack-v2``).
        agents: Particle-filter agents (``hold`` always runs, once).
        oracles: The likelihoods: None for the agent's own (image), else an oracle.
        particles: Particles per filter.
        episodes: With ``declared``, the first this many windows (None: all);
            otherwise this many seeded draws (None: 20).
        declared: Track the task's declared test windows.
        seed: First episode seed, first agent seed and the oracles' noise seed.
        agent_seeds: Agent seeds ``seed``, ``seed + 1``... per agent and likelihood.
        env_kwargs: Keyword arguments of ``gym.make`` (``data_dir``, ``split``...).
        progress: Show a progress bar.
        on_row: Called with each finished row (to save partial results).
        settings: Overrides of every agent's settings: ``fit.NAME`` its prior's,
            ``filter.NAME`` its filter's (as ``humotion-gym select``'s grid names them).
        done: Rows an interrupted run of the same arguments finished (as ``on_row``
            gave them), kept: the rest come out as in one run.

    Returns:
        ``{"task", "particles", "seed", "agent_seeds", "declared", "windows",
        "rows"}``, and ``"validation_persons"`` where ``env_kwargs``'s
        ``library`` is a validation fold (the persons tracked); each row
        ``{"agent", "likelihood", "oracle"`` (its settings or None), summary
        numbers (:func:`_summary`), ``"x_hold"`` (hold's mean error over the
        row's) and ``"episodes"``.

    Raises:
        ValueError: If a count is below 1, an agent is not a particle filter or
            ``done`` is not the first rows of this run.
        SettingsError: If a setting is not ``fit.NAME`` or ``filter.NAME`` of every
            agent (checked before any episode runs).
    """
    if agent_seeds < 1 or (episodes is not None and episodes < 1) or particles < 1:
        raise ValueError(
            f"episodes, agent_seeds, particles: expected at least 1, got {episodes}, "
            f"{agent_seeds}, {particles}"
        )
    env = make_env(task, env_kwargs)
    windows, listed = _windows(task, episodes, declared, env_kwargs)
    base = tracking_env(env)
    names = [a for a in agents if a != "hold"]
    build = _builder(env, names, particles, seed, settings or {})
    runs = _runs(names, oracles)
    rows = _done_rows(task, done, runs, len(windows), agent_seeds)
    total = len(windows) * (1 + len(names) * len(oracles) * agent_seeds)
    bar = tqdm(
        total=total, initial=sum(len(r["episodes"]) for r in rows),
        desc=f"oracle {task}: episodes", disable=not progress,
    )  # fmt: skip
    with bar, single_threaded_blas():
        for name, oracle in runs[len(rows) :]:
            eps = []
            for agent_seed in range(seed, seed + (1 if name == "hold" else agent_seeds)):
                agent = build(name, agent_seed)
                run_env: gym.Env = env
                if oracle is not None:
                    truth = TruthOracle(oracle, base.task.error_keypoint_indices, seed=seed)
                    agent = with_oracle(agent, truth)
                    run_env = OracleFeed(env, truth)
                for k, window in enumerate(windows):
                    record = diagnose_episode(agent, run_env, seed + k, window_options(window))
                    eps.append({"agent_seed": agent_seed, **record})
                    bar.update()
            row = {
                "agent": name, "likelihood": "none" if name == "hold" else _label(oracle),
                "oracle": None if oracle is None else vars(oracle), **_summary(eps),
                "episodes": eps,
            }  # fmt: skip
            row["x_hold"] = rows[0]["error_mm"] / row["error_mm"] if rows else 1.0
            rows.append(row)
            if on_row is not None:
                on_row(row)
    env.close()
    out = {
        "task": task, "particles": particles, "seed": seed, "agent_seeds": agent_seeds,
        "declared": declared, "windows": len(windows), "declared_windows": listed, "rows": rows,
    }  # fmt: skip
    library = (env_kwargs or {}).get("library")
    if library is not None and library.test_subjects is not None:  # a validation fold
        out["validation_persons"] = sorted(library.held_out)
    return out


def _windows(
    task: str, episodes: int | None, declared: bool, env_kwargs: Mapping[str, Any] | None
) -> tuple[list[tuple[str, int] | None], int]:
    """The windows :func:`run_split` tracks (None: a seeded draw), and the count declared."""
    if not declared:
        return [None] * (episodes or 20), 0
    listed: list[tuple[str, int] | None] = list(task_windows(task, env_kwargs))
    return listed[: episodes or len(listed)], len(listed)


def _runs(
    agents: Sequence[str], oracles: Sequence[OracleSettings | None]
) -> list[tuple[str, OracleSettings | None]]:
    """The rows of a run in order: ``hold``, then every agent with every likelihood."""
    names = [a for a in agents if a != "hold"]
    return [("hold", None)] + [(a, o) for a in names for o in oracles]


def check_done(
    task: str,
    done: Sequence[Mapping[str, Any]],
    agents: Sequence[str],
    oracles: Sequence[OracleSettings | None],
    episodes: int | None = None,
    declared: bool = True,
    agent_seeds: int = 1,
    env_kwargs: Mapping[str, Any] | None = None,
) -> None:
    """Refuse rows ``done`` that :func:`run_split` (same arguments) would refuse, running nothing.

    A resumed run checks every task's saved rows before its first task runs,
    not when the task they belong to starts.

    Raises:
        ValueError: Naming the first row that is not this run's.
    """
    windows, _ = _windows(task, episodes, declared, env_kwargs)
    _done_rows(task, done, _runs(agents, oracles), len(windows), agent_seeds)


def _done_rows(
    task: str,
    done: Sequence[Mapping[str, Any]],
    runs: Sequence[tuple[str, OracleSettings | None]],
    windows: int,
    agent_seeds: int,
) -> list[dict[str, Any]]:
    """``done`` checked to be the first rows of ``runs`` (ValueError naming one that is not)."""
    if len(done) > len(runs):
        raise ValueError(f"done: {len(done)} rows of {task}, but this run has {len(runs)}")
    for k, (row, (name, oracle)) in enumerate(zip(done, runs[: len(done)], strict=True)):
        want = (name, "none" if name == "hold" else _label(oracle))
        count = windows * (1 if name == "hold" else agent_seeds)
        got = (row.get("agent"), row.get("likelihood"))
        if got != want or len(row.get("episodes", ())) != count:
            raise ValueError(
                f"done: row {k + 1} of {task} is {got[0]} with {got[1]} "
                f"({len(row.get('episodes', ()))} episodes), but this run's is {want[0]} "
                f"with {want[1]} ({count} episodes)"
            )
    return [dict(row) for row in done]


def check_agents(
    task: str,
    agents: Sequence[str],
    particles: int,
    seed: int = 0,
    env_kwargs: Mapping[str, Any] | None = None,
    settings: Mapping[str, Any] | None = None,
) -> None:
    """Make each agent once on ``task`` as :func:`run_split` would, running nothing.

    A run over several tasks calls it for every task first, so that an agent
    that cannot track a later task is refused before the earlier ones run.

    Raises:
        ValueError: If an agent cannot track the task.
        SettingsError: As :func:`run_split`.
    """
    env = make_env(task, env_kwargs)
    try:
        _builder(env, [a for a in agents if a != "hold"], particles, seed, settings or {})
    finally:
        env.close()


def _builder(
    env: gym.Env, names: Sequence[str], particles: int, seed: int, settings: Mapping[str, Any]
) -> Callable[[str, int], Any]:
    """``build(name, agent_seed)``: an agent with ``settings``, each agent tried once first.

    Raises:
        SettingsError: If a setting is not ``fit.NAME`` or ``filter.NAME`` of every agent.
    """
    fit, search = agent_settings(settings)
    unknown = sorted(k for k in settings if not k.startswith((FIT_PREFIX, FILTER_PREFIX)))
    if unknown:
        raise SettingsError(f"settings: expected fit.NAME or filter.NAME, got {', '.join(unknown)}")
    if settings and not names:
        raise SettingsError("settings: given, but no particle-filter agent runs (hold takes none)")

    def build(name: str, agent_seed: int) -> Any:
        if name == "hold":
            return make(name, env, seed=agent_seed)
        return make(
            name, env, n_particles=particles, seed=agent_seed, fit_settings=fit,
            filter_settings=search,
        )  # fmt: skip

    for name in names:
        try:
            build(name, seed)
        except ValueError as exc:
            if not settings:
                raise
            raise SettingsError(f"{name}: {exc}") from None
    return build


def compact(result: Mapping[str, Any]) -> dict[str, Any]:
    """The result with each episode's numbers rounded to two decimals."""
    rows = [
        {**row, "episodes": [
            {k: round(v, 2) if isinstance(v, float) else v for k, v in e.items()}
            for e in row["episodes"]
        ]}
        for row in result["rows"]
    ]  # fmt: skip
    return {**result, "rows": rows}


def episode_rows(data: Any, path: str | Path) -> list[dict[str, Any]]:
    """A saved oracle run (``humotion-gym oracle --out``, read from ``path``) as rows.

    One leaderboard-like row per task, agent and likelihood, its agent named
    ``"AGENT LIKELIHOOD"`` (``"pf-cv 2d 1px"``; ``hold`` as it is) and each
    episode's ``mean_error_mm`` its error: what
    :func:`baselines.leaderboard.compare.compare_runs` reads.

    Raises:
        ValueError: If it is not an oracle run's results (the message names ``path``).
    """
    results = data.get("results") if isinstance(data, dict) else None
    if not isinstance(results, list) or not all(
        isinstance(r, dict) and isinstance(r.get("rows"), list) for r in results
    ):
        raise ValueError(f"{path}: expected an oracle run's results ('results' with 'rows')")
    rows = []
    for result in results:
        for row in result["rows"]:
            hold = row["agent"] == "hold"
            rows.append({
                "task": result["task"],
                "agent": row["agent"] if hold else f"{row['agent']} {row['likelihood']}",
                "particles": 0 if hold else result["particles"],
                "episodes": [
                    {"agent_seed": e.get("agent_seed", 0), "seed": e["seed"],
                     "mean_error_mm": e["error_mm"]}
                    for e in row["episodes"]
                ],
            })  # fmt: skip
    return rows


def _num(value: float | None, fmt: str = ".0f") -> str:
    return "-" if value is None else format(value, fmt)


def rows_table(result: Mapping[str, Any]) -> str:
    """Every row: error, aligned error, x hold, the depth split, reprojection, ESS."""
    lines = [
        "| agent | likelihood | mm | aligned mm | x hold | along / across mm "
        "| aligned along / across mm | reprojection px | ESS |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in result["rows"]:
        lines.append(
            f"| {r['agent']} | {r['likelihood']} | {_num(r['error_mm'])} | "
            f"{_num(r['aligned_mm'])} | {r['x_hold']:.2f} | "
            f"{_num(r['along_abs_mm'])} / {_num(r['across_mm'])} | "
            f"{_num(r['aligned_along_abs_mm'])} / {_num(r['aligned_across_mm'])} | "
            f"{_num(r['reprojection_px'], '.1f')} | {_num(r['ess'], '.1f')} |"
        )
    return "\n".join(lines)


def split_table(result: Mapping[str, Any]) -> str:
    """Per agent, the split: evidence (image - 2D), depth (the 2D run's), identity, search.

    Columns are left empty (``-``) where the run had no such likelihood; the
    first oracle of each kind is the one read (every 3D oracle gets a column).
    """
    by_agent: dict[str, dict[str, Mapping[str, Any]]] = {}
    three_d: list[str] = []
    for r in result["rows"]:
        if r["agent"] == "hold":
            continue
        kind = "image" if r["oracle"] is None else r["oracle"]["kind"]
        cells = by_agent.setdefault(r["agent"], {})
        key = r["likelihood"] if kind == "3d" else kind
        cells.setdefault(key, r)
        if kind == "3d" and key not in three_d:
            three_d.append(key)
    columns = [
        "agent", "image mm", "2D oracle mm", "evidence: image - 2D",
        "depth: 2D run along / across (aligned)", "2D unlabelled - 2D",
        *(f"search: {k} mm" for k in three_d),
    ]  # fmt: skip
    table = [columns]
    for agent, cells in by_agent.items():
        img, two, unl = cells.get("image"), cells.get("2d"), cells.get("2d-unlabelled")

        def gap(a: Mapping[str, Any] | None, b: Mapping[str, Any] | None) -> str:
            return "-" if a is None or b is None else f"{a['error_mm'] - b['error_mm']:+.0f}"

        depth = "-"
        if two is not None:
            depth = (
                f"{_num(two['along_abs_mm'])} / {_num(two['across_mm'])} "
                f"({_num(two['aligned_along_abs_mm'])} / {_num(two['aligned_across_mm'])})"
            )
        table.append([
            agent, _num(img and img["error_mm"]), _num(two and two["error_mm"]), gap(img, two),
            depth, gap(unl, two), *(_num(cells[k]["error_mm"]) if k in cells else "-"
                                    for k in three_d),
        ])  # fmt: skip
    return markdown_rows(table)


def markdown_report(results: Sequence[Mapping[str, Any]]) -> str:
    """Both tables for each task's result, under a heading of what it tracked.

    A run of a validation fold names its persons (``validation_persons``); a
    run of the test persons says nothing more.
    """
    parts = []
    for res in results:
        n, listed = res["windows"], res.get("declared_windows", 0)
        what = f"{n} seeded episodes"
        if res.get("validation_persons"):
            what += f" of the validation persons {', '.join(res['validation_persons'])}"
        if res["declared"]:
            what = f"the first {n} of {listed}" if n < listed else f"the {n}"
            what += " declared test windows"
        filters = any(r["agent"] != "hold" for r in res["rows"])  # hold alone has no split
        parts.append(
            f"## {res['task']}: {what}, {res['particles']} particles, "
            f"{res['agent_seeds']} agent seed(s) from {res['seed']}\n\n"
            + rows_table(res)
            + ("\n\n" + split_table(res) if filters else "")
        )
    return "\n\n".join(parts) + "\n"
