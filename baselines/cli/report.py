"""``humotion-gym report``: the report folder of a saved leaderboard.

::

    humotion-gym leaderboard --tasks ArmTrack-v2 --out runs/lb
    humotion-gym report runs/lb --out runs/lb-report --videos

Writes ``index.html`` (sortable tables, figures, videos), ``tables.md`` (the
Markdown tables the README pastes) and ``stats.json`` (every statistic).
``--out`` is a fresh folder, the run's own folder, or one holding an earlier
report of the same results file (``report.json`` names it): never another
run's folder or another run's report, which would leave a mix of two runs.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from baselines.cli._runs import held_run
from humotion_gym.cli._common import (
    CommandError,
    UsageError,
    add_command,
    add_data_dir,
    nonnegative_int,
    output_dir,
    refused_as,
    wrote,
)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``report``."""
    rp = add_command(
        subparsers, "report", "tables, figures, videos and index.html of a saved leaderboard",
        "humotion-gym report runs/lb/results.json --out runs/lb-report --videos",
    )  # fmt: skip
    rp.add_argument(
        "results", type=Path,
        help="a leaderboard's results: its --out folder, or the results.json (.gz) in it",
    )  # fmt: skip
    rp.add_argument(
        "--out", type=output_dir, required=True,
        help="the report folder (created if needed): a fresh one, the run's own folder, or one "
        "holding an earlier report of the same results file",
    )  # fmt: skip
    rp.add_argument(
        "--videos", action="store_true",
        help="re-run each cell's best, median and worst episode and write videos of them "
        "(costs up to one more run of each cell)",
    )  # fmt: skip
    rp.add_argument(
        "--video-agents", nargs="+", default=None, metavar="AGENT",
        help="with --videos: only these agents get videos (default: every agent)",
    )  # fmt: skip
    add_data_dir(rp)
    rp.add_argument(
        "--seed", type=nonnegative_int, default=None,
        help="seed of the bootstrap of the report's statistics: the cell statistics, the "
        "aggregate across tasks, the probabilities of improvement (stats.json and their "
        "tables) and the figures' intervals (default: the run's, so that the report rebuilds "
        "the one the run wrote); the leaderboard table and its verdicts keep the run's seed, "
        "as its table.md",
    )  # fmt: skip
    rp.add_argument(
        "--title", default="humotion_gym leaderboard",
        help="the page's title (default: humotion_gym leaderboard)",
    )  # fmt: skip
    rp.set_defaults(func=_cmd_report)


def _cmd_report(args: argparse.Namespace) -> int:
    from baselines.leaderboard.figures import figures_available
    from baselines.leaderboard.report import load_rows, results_file, write_report
    from baselines.leaderboard.videos import ReplayMismatch

    if args.video_agents and not args.videos:
        raise UsageError("--video-agents: only with --videos")
    args.results = results_file(args.results)
    if not args.results.is_file():
        raise FileNotFoundError(f"{args.results}: no such leaderboard file")
    _check_out(args.out, args.results)
    with refused_as(CommandError, (ValueError, UnicodeDecodeError)):
        rows, settings = load_rows(args.results)
    unknown = sorted(set(args.video_agents or []) - {r.get("agent") for r in rows})
    if unknown:
        agents = sorted({str(r.get("agent")) for r in rows})
        raise UsageError(
            f"--video-agents: no agent {', '.join(unknown)} in {args.results}; its agents are "
            f"{', '.join(agents)}"
        )
    env_kwargs = dict(settings.get("env_kwargs") or {})
    if args.data_dir:
        env_kwargs["data_dir"] = args.data_dir
    agents = set(args.video_agents or [])
    run_seed = int(settings.get("seed") or 0)
    with refused_as(CommandError, (ValueError, ReplayMismatch)):
        index = write_report(
            rows, args.out, videos=args.videos, env_kwargs=env_kwargs,
            seed=run_seed if args.seed is None else args.seed, table_seed=run_seed,
            video_cells=(lambda r: r["agent"] in agents) if agents else None, title=args.title,
            run=settings, source=args.results,
        )  # fmt: skip
    wrote(args.out / "tables.md", "Markdown tables")
    wrote(args.out / "stats.json", "every statistic")
    if figures_available():
        wrote(index, "open it in a browser")
    else:
        wrote(index, "the tables but no figures: install the plots extra for them")
    return 0


def _check_out(out: Path, results: Path) -> None:
    """Refuse an ``--out`` whose files are another run's: the report would mix two runs.

    The run's own folder is fine, and so is one holding an earlier report of the
    same results file (:func:`~baselines.leaderboard.report.reported_run`).

    Raises:
        UsageError: Naming ``--out`` and what it holds.
    """
    from baselines.leaderboard.report import REPORT_SOURCE, reported_run

    results = results.resolve()
    if out.resolve() == results.parent:
        return
    held = held_run(out)
    if held is not None:
        raise UsageError(
            f"--out: {out} holds another run, {held[0]} ({held[1]}); choose another folder"
        )
    report = reported_run(out)
    if report is not None and report[1] != str(results):
        of = report[1] or f"a run it does not name (no {REPORT_SOURCE})"
        raise UsageError(
            f"--out: {out} holds the report ({report[0]}) of another run, {of}; choose "
            "another folder"
        )
