"""``humotion-gym sweep``: difficulty curves, the leaderboard over environment settings.

::

    humotion-gym sweep --tasks BodyTrack-v2 --agents pf-cv pf-tree --particles 300
        --noise 0 4 8 16 --occluders 0 1 2 4 --episodes 5 --out runs/sweep

Each setting is varied on its own from the task's defaults; every value runs
the leaderboard (``hold`` included). Writes ``sweep.json`` (every episode),
``sweep.md`` (the curves as a table) and ``sweep.png`` (the curves).
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

from baselines.cli._args import (
    add_agents,
    add_engine,
    check_engine,
    check_policy_files,
    engine_errors,
    particle_count,
    tracked_task,
)
from humotion_gym.cli._common import (
    Distinct,
    UsageError,
    add_command,
    add_data_dir,
    add_int,
    add_json,
    add_seed,
    check_fresh_output,
    env_kwargs,
    episode_count,
    float_between,
    int_at_least,
    output_dir,
    output_file,
    print_json,
    refused_as,
    wrote,
)
from humotion_gym.files import write_text_atomically
from humotion_gym.render_scene import MAX_IMAGE_SIZE, MIN_IMAGE_SIZE, SCENE_MAXIMA

#: The settings a sweep varies, in ``--help`` order: each one's flag (``--NAME``, with
#: ``-`` for ``_``) takes values ``add_argument`` reads with these keywords.
_SETTINGS: dict[str, dict[str, Any]] = {
    "size": {
        "type": int_at_least(MIN_IMAGE_SIZE[1], MAX_IMAGE_SIZE[1]), "metavar": "PIXELS",
        "help": f"image sizes, width = height, {MIN_IMAGE_SIZE[1]} to {MAX_IMAGE_SIZE[1]}",
    },
    "background": {"choices": ["flat", "clutter"], "help": "backgrounds"},
    "noise": {
        "type": float_between(0.0, SCENE_MAXIMA["noise_sigma"]), "metavar": "SIGMA",
        "help": "sensor noise levels, grey levels",
    },
    "occluders": {
        "type": int_at_least(0, int(SCENE_MAXIMA["occluders"])), "metavar": "N",
        "help": "numbers of occluders",
    },
    "blur": {
        "type": float_between(0.0, SCENE_MAXIMA["blur_sigma"]), "metavar": "SIGMA",
        "help": "blur levels, pixels",
    },
    "frame_skip": {"type": int_at_least(1, 100), "metavar": "K", "help": "frame skips"},
}  # fmt: skip


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``sweep``."""
    sw = add_command(
        subparsers, "sweep",
        "difficulty curves: the leaderboard over a grid of environment settings",
        "humotion-gym sweep --tasks BodyTrack-v2 --noise 0 4 8 16 --episodes 5 --out runs/sweep",
        details="Each setting is varied on its own from the task's defaults; every value runs "
        "the leaderboard (hold included). Writes sweep.json (every episode), sweep.md (the "
        "curves as a table) and sweep.png (the curves).",
    )  # fmt: skip
    sw.add_argument(
        "--tasks", type=tracked_task, nargs="+", action=Distinct, default=["BodyTrack-v2"],
        metavar="TASK",
        help="task ids (default: BodyTrack-v2)",
    )  # fmt: skip
    add_agents(sw)
    sw.add_argument(
        "--particles", type=particle_count, nargs="+", action=Distinct, default=[300],
        metavar="N", help="particle counts of the particle filters (default: 300)",
    )  # fmt: skip
    add_int(sw, "--episodes", 5, "episodes per cell and value", episode_count)
    grid = sw.add_argument_group("settings (each one given is swept on its own)")
    for name, flag in _SETTINGS.items():
        grid.add_argument(
            "--" + name.replace("_", "-"), nargs="+", action=Distinct, default=None,
            dest=f"sweep_{name}",
            **{**flag, "help": flag["help"] + " (default: not swept)"},
        )  # fmt: skip
    add_engine(sw)
    add_seed(sw, "seed of the first episode")
    add_data_dir(sw)
    sw.add_argument(
        "--out", type=output_dir, required=True,
        help="folder for sweep.json, sweep.md and sweep.png, and each point's episodes as "
        "they finish, in points/ (created if needed)",
    )  # fmt: skip
    sw.add_argument(
        "--resume", action="store_true",
        help="continue the sweep saved in OUT, given with the same tasks, agents, particles, "
        "episodes, seed, settings and data: each point's run resumes where it stopped "
        "(default: an OUT holding a sweep is refused)",
    )  # fmt: skip
    sw.add_argument(
        "--figure", type=output_file(".png"), default=None,
        help="also write the figure here (e.g. docs/img/sweep_noise_occluders.png; default: none)",
    )  # fmt: skip
    add_json(
        sw,
        "print the curves (each cell's IQM, interval, mean and lost share per value) "
        "and what did not run as JSON, instead of the table",
    )
    sw.set_defaults(func=_cmd_sweep)


def _flag(setting: str) -> str:
    """The flag that gives a setting of :func:`baselines.sweep.sweep_settings`."""
    if setting in ("version", "env_kwargs", "grid"):  # the file's format, or no flag's
        return setting
    return "--data-dir" if setting == "data" else "--" + setting.replace("_", "-")


def _check_out(args: argparse.Namespace) -> None:
    """Refuse ``--out`` holding a sweep without ``--resume``, and ``--resume`` with none there.

    (``run_sweep`` compares a resumed sweep's settings with the saved ones.)
    """
    from baselines import sweep

    if not args.resume:
        check_fresh_output(args.out, ["sweep.json", sweep.SETTINGS_FILE, "points"], "a sweep")
        return
    if not (args.out / sweep.SETTINGS_FILE).is_file() and not (args.out / "points").is_dir():
        raise UsageError(f"--resume: no sweep to resume in {args.out} (start one without it)")


def _cmd_sweep(args: argparse.Namespace) -> int:
    import importlib.util

    from baselines import sweep
    from baselines.leaderboard.results import ResumeError

    grid = {name: values for name in _SETTINGS if (values := getattr(args, f"sweep_{name}"))}
    if not grid:
        flags = ", ".join("--" + name.replace("_", "-") for name in _SETTINGS)
        raise UsageError(f"nothing to sweep: give at least one of {flags}")
    check_engine(args)
    _check_out(args)
    check_policy_files(args.agents)
    engine = None
    if args.engine != "inprocess":
        engine = {"engine": args.engine, "workers": args.workers, "address": args.address}
    # the saved sweep's settings (checked before any point runs), or a point's saved run
    # of other code or another policy file: the arguments conflict
    with refused_as(UsageError, ResumeError, "--resume: "), engine_errors():
        result = sweep.run_sweep(
            args.tasks, args.agents, args.particles, grid, args.episodes, args.seed,
            env_kwargs(args), engine_options=engine, out=args.out, resume=args.resume,
            setting_name=_flag,
        )  # fmt: skip
    args.out.mkdir(parents=True, exist_ok=True)
    say = (lambda *_: None) if args.json else wrote  # --json: stdout holds the JSON alone
    say(sweep.save(result, args.out / "sweep.json"), "every episode at every setting")
    table = sweep.markdown(result)
    write_text_atomically(args.out / "sweep.md", table + "\n")
    if args.json:
        problems = [{"kind": kind, "what": what} for kind, what in sweep.problems(result)]
        print_json({"curves": sweep.curves(result), "not_run": problems})
    else:
        print(table)
    say(args.out / "sweep.md", "the curves as a table")
    failed = [what for kind, what in sweep.problems(result) if kind == "error"]
    for what in failed:
        print(f"error: {what}", file=sys.stderr)
    if importlib.util.find_spec("matplotlib") is None:
        print(
            "no figure: matplotlib is not installed (pip install -e '.[plots]' adds it)",
            file=sys.stderr if args.json else sys.stdout,
        )
        return 1 if failed else 0
    title = (
        f"{', '.join(args.tasks)}; {args.episodes} episodes per point; "
        f"particles {', '.join(map(str, args.particles))}"
    )
    for path in [args.out / "sweep.png"] + ([args.figure] if args.figure else []):
        say(sweep.figure(result, path, title), "difficulty curves")
    return 1 if failed else 0
