"""``humotion-gym leaderboard``: agents x tasks x particle counts x seeded episodes.

::

    humotion-gym leaderboard --tasks ArmTrack-v2 --agents pf-cv pf-tree --particles 300 3000
    humotion-gym leaderboard --engine ray --workers 2 --out results/lb   # on a local Ray
    humotion-gym leaderboard --engine ray --workers 2 --out results/lb --resume

Exit codes (the command's ``details``): 0 when every cell ran or was skipped;
1 when a cell failed; 2 on a usage error; 130 when interrupted.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
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
from baselines.cli._runs import LEADERBOARD_RUN, held_run
from humotion_gym.cli import interrupted
from humotion_gym.cli._common import (
    CommandError,
    UsageError,
    add_command,
    add_data_dir,
    add_json,
    add_seed,
    env_kwargs,
    episode_count,
    float_between,
    output_dir,
    print_json,
    refused_as,
    wrote,
)
from humotion_gym.render_scene import SCENE_MAXIMA

#: Episodes per cell drawn from the seeds when ``--episodes`` is not given.
DEFAULT_EPISODES = 20

#: Printed under the table: what its columns mean.
LEGEND = (
    "mean error: keypoint error over the episodes' frames, mm, with a 95% bootstrap "
    "interval; IQM: interquartile mean over the episodes (the mean of the middle 50%); "
    "x hold: hold's mean error over the row's (above 1: better than doing nothing); "
    "beats hold: paired episodes where the row's error is lower; lost track: episodes "
    "whose error stayed above the task's lost-track threshold long enough to count as lost."
)
#: Printed after :data:`LEGEND` when a run has several agent seeds.
SEEDS_LEGEND = (
    "With several agent seeds: mean error and x hold are over every seed's episodes, their "
    "intervals resample the episodes and then the agent seeds within each; seed spread: the "
    "lowest and highest of the seeds' mean errors; the verdict takes the lower bound of the "
    "best reference filter's x hold interval."
)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``leaderboard``."""
    lb = add_command(
        subparsers, "leaderboard", "agents x tasks x particle counts x seeded episodes, with hold",
        "humotion-gym leaderboard --tasks ArmTrack-v2 --agents pf-cv pf-tree --out runs/lb",
        details="Exit codes: 0 when every cell ran or was skipped; 1 when a cell failed (the "
        "table shows it, stderr names it); 2 on a usage error (an --out holding a run without "
        "--resume, another command's run or a report of another run, or --resume with "
        "another grid or other settings); 130 when interrupted "
        "(--out keeps what finished).",
    )  # fmt: skip
    lb.add_argument(
        "--tasks", type=tracked_task, nargs="+", default=["ArmTrack-v2", "BodyTrack-v2"],
        metavar="TASK", help="task ids (default: ArmTrack-v2 BodyTrack-v2)",
    )  # fmt: skip
    add_agents(lb, "hold always runs as the floor")
    lb.add_argument(
        "--particles", type=particle_count, nargs="+", default=[300, 3000], metavar="N",
        help="particle counts of the particle filters (default: 300 3000)",
    )  # fmt: skip
    lb.add_argument(
        "--episodes", type=episode_count, default=None,
        help=f"episodes per cell, drawn from the seeds (default: {DEFAULT_EPISODES}; not with "
        "--declared, whose lists fix them)",
    )  # fmt: skip
    lb.add_argument(
        "--declared", action="store_true",
        help="run each task's declared test episodes (fixed windows over every test clip, the "
        "same for every agent; intervals resample clips) instead of --episodes drawn ones",
    )  # fmt: skip
    add_seed(lb, "seed of the first episode")
    lb.add_argument(
        "--agent-seeds", type=episode_count, default=1, metavar="K",
        help="agent seeds per cell (SEED ... SEED+K-1), each on the same episodes; above 1 the "
        "table adds the seeds' spread and an interval to x hold, and each task's verdict "
        "takes that interval's lower bound (default: 1)",
    )  # fmt: skip
    add_data_dir(lb)
    lb.add_argument(
        "--out", type=output_dir, default=None, metavar="FOLDER",
        help="results folder: each finished episode is saved as it finishes (episodes.jsonl), "
        "then results.json, table.md and the report (default: none)",
    )  # fmt: skip
    lb.add_argument(
        "--resume", action="store_true",
        help="continue the run saved in --out FOLDER, skipping its finished episodes",
    )  # fmt: skip
    lb.add_argument(
        "--videos", action="store_true",
        help="with --out: also videos of each cell's best, median and worst episode (re-run)",
    )  # fmt: skip
    lb.add_argument(
        "--no-report", action="store_true",
        help="with --out: results.json and table.md only, no figures or index.html",
    )  # fmt: skip
    add_engine(lb)
    add_json(lb, "print the rows as JSON instead of the table")
    lb.add_argument(
        "--background", choices=["flat", "clutter"], default=None,
        help="scene background, a difficulty setting (default: the task's)",
    )  # fmt: skip
    lb.add_argument(
        "--noise", type=float_between(0.0, SCENE_MAXIMA["noise_sigma"]), default=None,
        help="sensor noise, a difficulty setting (default: the task's)",
    )  # fmt: skip
    lb.set_defaults(func=_cmd_leaderboard)


def _check_results_folder(args: argparse.Namespace) -> None:
    """Refuse ``--out`` holding a run without ``--resume``, and a resume on another grid.

    Another command's run, a leaderboard's results without their episodes, or
    a report alone are refused with or without ``--resume``; so is a resume
    whose grid or seeds would drop saved episodes from the table.

    Raises:
        UsageError: Naming ``--out`` or ``--resume``.
    """
    from baselines.leaderboard import EPISODES_FILE, ResultsFolder, grid_cells
    from baselines.leaderboard.report import reported_run

    held = held_run(args.out)
    if held is not None and held[0] != LEADERBOARD_RUN:
        raise UsageError(
            f"--out: {args.out} holds {held[0]} ({held[1]}), not a leaderboard run; give "
            "another --out"
        )
    report = reported_run(args.out) if held is None else None
    if report is not None:  # no run of its own: its report is another run's
        raise UsageError(
            f"--out: {args.out} holds a report of another run ({report[0]}); give another --out"
        )
    folder = ResultsFolder(args.out)
    episodes = folder.episodes_path
    holds_run = folder.run_path.is_file() or (episodes.is_file() and episodes.stat().st_size > 0)
    if not holds_run and held is not None and held[1] != EPISODES_FILE:
        raise UsageError(
            f"--out: {args.out} already holds a leaderboard run's results ({held[1]}) but no "
            "episodes to resume; choose another folder or move them away"
        )
    if not args.resume:
        if holds_run:
            raise UsageError(
                f"--out: {args.out} already holds a run; add --resume to continue it or "
                "choose another folder"
            )
        return
    if not holds_run:
        raise UsageError(f"--resume: {args.out} holds no run to continue (start one without it)")
    cells = set(grid_cells(args.tasks, args.agents, args.particles))
    # a declared run's episode seeds follow its lists: only its cells are checked
    seeds = None if args.declared else range(args.seed, args.seed + args.episodes)
    try:
        saved = [  # finished episodes: a failed one is rerun, or dropped with its agent
            (r["task"], r["agent"], int(r["particles"]), int(r["seed"]))
            for r in folder.read()
            if "result" in r
        ]
    except (KeyError, TypeError, ValueError) as exc:  # ResumeError: a line that is not JSON
        raise CommandError(f"--resume: {args.out}: unreadable episodes ({exc})") from None
    other_cells = sorted({k[:3] for k in saved if k[:3] not in cells})
    other_seeds = sorted({k[3] for k in saved if seeds is not None and k[3] not in seeds})
    if other_seeds and not other_cells:
        assert seeds is not None
        shown = ", ".join(map(str, other_seeds[:5])) + (" ..." if len(other_seeds) > 5 else "")
        raise UsageError(
            f"--resume: {args.out} holds episodes of seeds {shown}, outside this run's "
            f"{seeds.start}-{seeds.stop - 1} (--seed {args.seed}, --episodes {args.episodes}); "
            "give the run's --seed and --episodes"
        )
    if other_cells:
        shown = ", ".join(f"{a} on {t} ({n} particles)" for t, a, n in other_cells[:3])
        raise UsageError(
            f"--resume: {args.out} holds episodes outside this grid ({shown}"
            f"{' ...' if len(other_cells) > 3 else ''}); give the run's --tasks, --agents, "
            "--particles, --episodes and --seed"
        )


def _unless_default(tasks: Sequence[str], field: str, value: Any) -> Any:
    """``value``, or None where it is every task's own scene ``field``."""
    from humotion_gym.envs import get_task
    from humotion_gym.render_scene import SceneOptions

    if value is None:
        return None
    own = {getattr(SceneOptions(**dict(get_task(t).scene)), field) for t in tasks}
    return None if own == {value} else value


def _check_flags(args: argparse.Namespace) -> None:
    """Refuse flags that conflict with each other (UsageError, naming one); set ``--episodes``."""
    from baselines.leaderboard.run import check_labels

    with refused_as(UsageError, ValueError, "--"):
        check_labels(args.agents)
    if args.resume and args.out is None:
        raise UsageError("--resume: needs --out FOLDER, the run to continue")
    if (args.videos or args.no_report) and args.out is None:
        given = [f for f, on in (("--videos", args.videos), ("--no-report", args.no_report)) if on]
        raise UsageError(f"{', '.join(given)}: need{'s' * (len(given) == 1)} --out FOLDER")
    if args.videos and args.agent_seeds > 1:
        raise UsageError("--videos: a video replays one agent seed; drop --agent-seeds")
    if args.declared and args.episodes is not None:
        raise UsageError(
            "--episodes: the declared test lists fix each task's episodes; leave it out with "
            "--declared"
        )
    if args.episodes is None:
        args.episodes = DEFAULT_EPISODES
    check_engine(args)


def _cmd_leaderboard(args: argparse.Namespace) -> int:
    from baselines.leaderboard import (
        ResumeError,
        default_command,
        markdown_table,
        run_leaderboard,
        validity_lines,
    )
    from baselines.leaderboard.videos import ReplayMismatch

    _check_flags(args)
    if args.out is not None and args.out.suffix == ".json":
        raise UsageError(
            f"--out: expected a results folder (it holds results.json), got the file {args.out}"
        )
    # a difficulty at every task's own value is no setting: saved without it, resumed with it
    args.background = _unless_default(args.tasks, "background", args.background)
    args.noise = _unless_default(args.tasks, "noise_sigma", args.noise)
    if args.out is not None:
        _check_results_folder(args)
    check_policy_files(args.agents)
    kwargs = env_kwargs(args)
    if args.background:
        kwargs["background"] = args.background
    if args.noise is not None:
        kwargs["noise"] = args.noise
    command = default_command(
        args.tasks, args.agents, args.particles, args.episodes, args.seed,
        data_dir=args.data_dir, background=args.background, noise=args.noise,
        engine=args.engine, workers=args.workers, address=args.address, out=args.out,
        videos=args.videos, no_report=args.no_report,
        agent_seeds=args.agent_seeds if args.agent_seeds != 1 else None,
        declared=args.declared, imports=args.imports,
    )  # fmt: skip
    try:
        with engine_errors():
            rows = run_leaderboard(
                args.tasks, args.agents, args.particles, args.episodes, args.seed, kwargs,
                engine=args.engine, workers=args.workers, address=args.address, out=args.out,
                resume=args.resume, command=command, report=not args.no_report,
                videos=args.videos, agent_seeds=args.agent_seeds, declared=args.declared,
            )  # fmt: skip
    except ResumeError as exc:  # the saved run's other settings: the arguments conflict
        raise UsageError(f"--resume: {exc}") from None
    except ReplayMismatch as exc:  # a video's episode did not reproduce: the run is saved
        raise CommandError(f"--videos: {exc}") from None
    except KeyboardInterrupt as exc:
        where = (
            f"; the finished episodes are saved in {args.out}; to finish it: {command} --resume"
            if args.out
            else ""
        )
        return interrupted(exc, "humotion-gym leaderboard", where)
    failed = [r for r in rows if "error" in r]
    if args.json:
        print_json({"rows": rows, "validity": validity_lines(rows)})
    else:
        print(markdown_table(rows))
        for line in validity_lines(rows):
            print(line)
        print(LEGEND)
        if args.agent_seeds > 1:
            print(SEEDS_LEGEND)
        if args.out:
            report = "" if args.no_report else ", the report (index.html)"
            wrote(args.out, f"results.json, table.md, run.json, episodes.jsonl{report}")
    for r in failed:
        print(
            f"error: {r['agent']} on {r['task']} ({r['particles']} particles): {r['error']}",
            file=sys.stderr,
        )
    return 1 if failed else 0
