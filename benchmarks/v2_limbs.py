"""Benchmark v2's figure: palettes, floor, elevation and framing, on validation persons.

Each variant of version 1's scene or camera is run on BodyTrack-v2 and WalkTrack-v2
with a particle filter (``pf-mix``, 300 particles, two agent seeds) and with
``hold`` (the initial pose every frame: the floor any tracker must beat), on a
validation fold of the training persons (never the test persons): the priors
fit on the rest of the training split. Every variant runs the same episode
seeds, which pick the same clips, starts, backgrounds and noise (none of the
variants draws from the generators before them), so variants are compared
episode by episode as well as by their intervals.

Usage::

    python benchmarks/v2_limbs.py --data-dir ../shared/mocap --episodes 80 \\
        --seeds 0 1 2 --out /tmp/v2_limbs.json

``--out`` resumes: the cells already in the file are kept and only the
missing task and variant cells run, so an interrupted run goes on where it
stopped. A file whose cells were run with another ``--agent``, ``--episodes``
or ``--seeds`` is refused (its episodes would not pair with the new ones):
give another ``--out`` for other settings.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from baselines.agents import make
from baselines.leaderboard.evaluation import evaluate
from baselines.leaderboard.stats import bootstrap_ci
from baselines.observation import task_model
from humotion_gym import body
from humotion_gym.body import CONE_NAMES
from humotion_gym.envs.pose_tracking import PoseTrackingEnv
from humotion_gym.envs.tasks import get_task
from humotion_gym.mocap.library import MotionLibrary, load_library
from humotion_gym.render_scene import FIGURE_PALETTES

#: The held-out training persons (a validation fold; see MotionLibrary.validation_fold).
VALIDATION_SUBJECTS = ("cmu-01", "cmu-05", "cmu-07")


class Variant(NamedTuple):
    """A scene and camera variant, and whether the tracker reads the cones' colours.

    Attributes:
        palette: A name in ``FIGURE_PALETTES``.
        elevation: Degrees added to the task camera's elevation.
        floor: Whether the floor is drawn.
        margin: The camera's margin, or None for the task's.
        appearance: The likelihood's ``appearance_weight`` (the cones' colours read
            at the first frame), or None for the task's (0 on the body tasks).
    """

    palette: str
    elevation: float = 0.0
    floor: bool = False
    margin: float | None = None
    appearance: float | None = None
    sleeves: tuple[int, int, int] | None = None


def _with_sleeves(palette: str, sleeves: tuple[int, int, int]) -> tuple[tuple[int, ...], ...]:
    """A named palette with both upper arms in another colour (candidate palettes)."""
    colors = list(FIGURE_PALETTES[palette])
    for name in ("r_upper_arm", "l_upper_arm"):
        colors[CONE_NAMES.index(name)] = sleeves
    return tuple(colors)


VARIANTS: dict[str, Variant] = {
    "a v1": Variant("v1"),
    "b shaded": Variant("shaded"),
    "c sided": Variant("sided"),
    "d shaded+elev30+floor": Variant("shaded", 30.0, True),
    "e shaded+margin0": Variant("shaded", margin=0.0),
    "f shaded+elev30": Variant("shaded", 30.0),
    "g shaded+floor": Variant("shaded", floor=True),
    "h v1+appearance": Variant("v1", appearance=1.0),
    "i shaded+appearance": Variant("shaded", appearance=1.0),
    "j sided+appearance": Variant("sided", appearance=1.0),
    "k green sleeves": Variant("v1", sleeves=(0, 60, 20)),
    "l yellow sleeves": Variant("v1", sleeves=(250, 210, 0)),
}


def variant_env(task: str, library: MotionLibrary, variant: str) -> PoseTrackingEnv:
    """The task's environment on ``library`` with a variant's scene and camera."""
    palette, elevation, floor, margin, _, sleeves = VARIANTS[variant]
    # the variants are changes of version 1's look (its camera and palette)
    v1 = get_task(f"{get_task(task).family}-v1")
    spec = dataclasses.replace(get_task(task), camera=v1.camera, scene=v1.scene)
    camera = dataclasses.replace(
        spec.camera,
        elevation_deg=spec.camera.elevation_deg + elevation,
        margin=spec.camera.margin if margin is None else margin,
    )
    # a validation fold's "test" persons are the validation persons
    env = PoseTrackingEnv(
        task=dataclasses.replace(spec, camera=camera), library=library, split="test",
        terminate_on_lost=False,
    )  # fmt: skip
    if sleeves is None:
        env.scene = dataclasses.replace(env.scene, palette=palette, floor=floor)
    else:
        colors = _with_sleeves(palette, sleeves)
        env.scene = dataclasses.replace(env.scene, palette=None, figure_colors=colors, floor=floor)
    return env


def run_cell(
    task: str, library: MotionLibrary, variant: str, agent: str, episodes: int, seeds: Sequence[int]
) -> dict[str, Any]:
    """Per-episode mean errors of ``agent`` (one row per agent seed) and of ``hold``."""
    env = variant_env(task, library, variant)
    clips = sorted({m.subject for m in env.clips})
    if not set(clips) <= set(VALIDATION_SUBJECTS):
        raise ValueError(f"run_cell: the environment tracks {clips}, not validation persons")
    started = time.perf_counter()
    model = task_model(env.task)
    if VARIANTS[variant].appearance is not None:
        model = dataclasses.replace(model, appearance_weight=VARIANTS[variant].appearance)
    runs = []
    for s in seeds:
        tracker = make(agent, env, n_particles=300, seed=s, observation_model=model)
        results = evaluate(tracker, env, episodes, seed=1000)
        runs.append([r.mean_error_mm for r in results])
    hold = evaluate(make("hold", env), env, episodes, seed=1000)
    return {
        "task": task,
        "variant": variant,
        "agent": agent,
        "episodes": episodes,
        "seeds": list(seeds),
        "subjects": clips,
        "clip_ids": [r.clip_id for r in hold],
        "agent_errors_mm": runs,
        "hold_errors_mm": [r.mean_error_mm for r in hold],
        "seconds": time.perf_counter() - started,
    }


def figure_heights(task: str, library: MotionLibrary, variant: str, episodes: int) -> float:
    """Median height in pixels of the figure's keypoints at the episodes' first frames."""
    env = variant_env(task, library, variant)
    heights = []
    for k in range(episodes):
        env.reset(seed=1000 + k)
        keypoints = body.forward_kinematics(env.true_pose(), env.shape)
        v = env.camera.project(keypoints)[:, 1]
        heights.append(float(np.nanmax(v) - np.nanmin(v)))
    return float(np.median(heights))


def clip_clustered_ci(
    values: np.ndarray, clip_ids: Sequence[str], n_resamples: int = 4000, seed: int = 0
) -> tuple[float, float]:
    """95% percentile bootstrap interval of the mean, resampling whole clips.

    Episodes of one clip (other start frames) are not independent; with few
    clips (WalkTrack's validation persons have 13) resampling clips gives the
    honest interval.
    """
    clips = sorted(set(clip_ids))
    index = np.array([clips.index(c) for c in clip_ids])
    sums = np.bincount(index, weights=values, minlength=len(clips))
    counts = np.bincount(index, minlength=len(clips))
    rng = np.random.default_rng(seed)
    picks = rng.integers(0, len(clips), (n_resamples, len(clips)))
    means = sums[picks].sum(axis=1) / counts[picks].sum(axis=1)
    lo, hi = np.percentile(means, [2.5, 97.5])
    return float(lo), float(hi)


def summarize(
    cells: list[dict[str, Any]], references: Sequence[str] = ("a v1", "b shaded")
) -> list[dict[str, Any]]:
    """Each cell's mean error with its bootstrap interval, x-hold, and paired changes.

    The change against each reference variant of the same task is the mean over
    episodes of the difference of the per-episode errors (averaged over agent
    seeds), with its bootstrap interval: the variants run the same episodes.
    """
    per_task: dict[str, dict[str, np.ndarray]] = {}
    for c in cells:
        per_task.setdefault(c["task"], {})[c["variant"]] = np.mean(c["agent_errors_mm"], axis=0)
    rows = []
    for c in cells:
        per_episode = per_task[c["task"]][c["variant"]]
        hold = np.asarray(c["hold_errors_mm"])
        row = {
            "task": c["task"],
            "variant": c["variant"],
            "agent": c["agent"],
            "mean_mm": float(per_episode.mean()),
            "ci": bootstrap_ci(per_episode, seed=0),
            "hold_mm": float(hold.mean()),
            "hold_ci": bootstrap_ci(hold, seed=0),
            "x_hold": float(per_episode.mean() / hold.mean()),
            "paired": {},
        }
        for ref in references:
            if ref in per_task[c["task"]] and ref != c["variant"]:
                diff = per_episode - per_task[c["task"]][ref]
                row["paired"][ref] = (
                    float(diff.mean()),
                    bootstrap_ci(diff, seed=0),
                    clip_clustered_ci(diff, c["clip_ids"]),
                )
        rows.append(row)
    return rows


def markdown(rows: list[dict[str, Any]], references: Sequence[str] = ("a v1", "b shaded")) -> str:
    """The summary as a Markdown table, sorted by task and variant; its agent named."""
    head = " | ".join(f"vs {ref}: mm [episodes CI] [clips CI]" for ref in references)
    agent = " / ".join(sorted({r["agent"] for r in rows}))
    lines = [
        f"| task | variant | {agent} mm [95% CI] | hold mm | x-hold | {head} |",
        "|---" * (5 + len(references)) + "|",
    ]
    for r in sorted(rows, key=lambda r: (r["task"], r["variant"])):
        changes = []
        for ref in references:
            if ref in r["paired"]:
                mean, (lo, hi), (clo, chi) = r["paired"][ref]
                changes.append(f"{mean:+.1f} [{lo:+.1f}, {hi:+.1f}] [{clo:+.1f}, {chi:+.1f}]")
            else:
                changes.append("")
        lines.append(
            f"| {r['task']} | {r['variant']} | {r['mean_mm']:.1f} [{r['ci'][0]:.1f}, "
            f"{r['ci'][1]:.1f}] | {r['hold_mm']:.0f} | {r['x_hold']:.3f} | {' | '.join(changes)} |"
        )
    return "\n".join(lines)


def read_results(out: Path) -> list[dict[str, Any]]:
    """The cells of a results file that ``--out`` names.

    Raises:
        ValueError: Naming the file, if it cannot be read or holds no cells.
    """
    try:
        cells = json.loads(out.read_text())["cells"]
    except (OSError, ValueError, KeyError, TypeError) as err:
        why = f"no {err} entry" if isinstance(err, KeyError) else str(err)
        raise ValueError(f"{out}: not a results file of this script ({why})") from None
    if not isinstance(cells, list):
        raise ValueError(f"{out}: not a results file of this script (its cells are no list)")
    return cells


def resumed_cells(
    out: Path, agent: str, episodes: int, seeds: Sequence[int]
) -> list[dict[str, Any]]:
    """The cells already in ``out`` (none where it does not exist), to run the rest.

    Raises:
        ValueError: Naming the file, the cell and the setting, if a cell was
            run with another agent, number of episodes or agent seeds (its
            episodes would not pair with the new cells'), or the file is unreadable.
    """
    if not out.exists():
        return []
    cells = read_results(out)
    wanted = {"agent": agent, "episodes": episodes, "seeds": list(seeds)}
    for c in cells:
        # a cell written before its episodes and seeds were kept: their counts
        had = {
            "agent": c.get("agent"),
            "episodes": c.get("episodes", len(c.get("hold_errors_mm", []))),
            "seeds": c.get("seeds"),
        }
        if had["seeds"] is None and len(c.get("agent_errors_mm", [])) != len(seeds):
            had["seeds"] = f"{len(c.get('agent_errors_mm', []))} seeds"
        differ = [
            f"{key} {had[key]} (given {wanted[key]})"
            for key in wanted
            if had[key] is not None and had[key] != wanted[key]
        ]
        if differ:
            raise ValueError(
                f"{out}: its {c.get('task')} {c.get('variant')!r} cell was run with "
                f"{', '.join(differ)}; --out resumes a run of the same --agent, --episodes "
                "and --seeds only: give another --out"
            )
    return cells


def main(argv: Sequence[str] | None = None) -> None:
    """Run the variants and write the cells and their summary as JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--data-dir",
        default=None,
        help="the real motion capture (e.g. ../shared/mocap; the validation persons are "
        "CMU's): needed unless --table",
    )
    parser.add_argument("--episodes", type=int, default=12)
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    parser.add_argument("--agent", default="pf-mix")
    parser.add_argument("--tasks", nargs="+", default=["BodyTrack-v2", "WalkTrack-v2"])
    parser.add_argument("--variants", nargs="+", default=list(VARIANTS))
    parser.add_argument(
        "--out",
        type=Path,
        default=Path("/tmp/v2_limbs.json"),
        help="the results' JSON; an existing one is resumed: its cells are kept and only "
        "the missing ones run (refused if run with another --agent, --episodes or --seeds)",
    )
    parser.add_argument(
        "--table", action="store_true", help="only print the table of the results in --out"
    )
    parser.add_argument(
        "--heights", action="store_true", help="only print the figure's median height per cell"
    )
    args = parser.parse_args(argv)
    try:
        if args.table:
            print(markdown(summarize(read_results(args.out))))
            return
        # before the library loads and the first cell runs
        cells = (
            [] if args.heights else resumed_cells(args.out, args.agent, args.episodes, args.seeds)
        )
    except ValueError as err:
        parser.error(f"--out: {err}")
    if args.data_dir is None:
        parser.error("--data-dir: give the real motion capture (e.g. ../shared/mocap)")
    library = load_library([args.data_dir], fps=30.0, progress=False)
    fold = library.validation_fold(list(VALIDATION_SUBJECTS))
    if args.heights:
        for task in args.tasks:
            for variant in args.variants:
                height = figure_heights(task, fold, variant, args.episodes)
                print(f"{task} {variant}: median figure height {height:.1f} px", flush=True)
        return
    done = {(c["task"], c["variant"]) for c in cells}
    for task in args.tasks:
        for variant in args.variants:
            if (task, variant) in done:
                continue
            cells.append(run_cell(task, fold, variant, args.agent, args.episodes, args.seeds))
            args.out.parent.mkdir(parents=True, exist_ok=True)
            rows = summarize(cells)
            args.out.write_text(json.dumps({"cells": cells, "summary": rows}, indent=1))
            print(json.dumps(rows[-1]), f"{cells[-1]['seconds']:.0f} s", flush=True)
    print(markdown(summarize(cells)))


if __name__ == "__main__":
    main()
