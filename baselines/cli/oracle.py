r"""``humotion-gym oracle``: each agent's error with its image likelihood and with truth oracles.

::

    humotion-gym oracle --task BodyTrack-v2 --agents pf-cv pf-mix --declared --episodes 12 \\
        --noise-mm 10 --data-dir ../shared/mocap --out results/oracle
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from baselines.cli._args import Settings, add_particles, key_setting, tracked_task
from baselines.cli._runs import (
    ORACLE_RUN,
    PARTIAL,
    RESULTS,
    UNFINISHED_ORACLE_RUN,
    held_run,
)
from humotion_gym.cli import interrupted
from humotion_gym.cli._common import (
    CommandError,
    Distinct,
    UsageError,
    add_command,
    add_data_dir,
    add_int,
    add_json,
    add_seed,
    env_kwargs,
    episode_count,
    output_dir,
    positive_float,
    print_json,
    refused_as,
    wrote,
)
from humotion_gym.files import read_json, write_json_gz, write_text_atomically

#: The likelihoods by default: the agents' own and each oracle at its default noise.
DEFAULT_ORACLES = ("image", "2d", "2d-unlabelled", "3d")


def _filter_agent(text: str) -> str:
    """An argparse ``type``: a registered particle-filter agent (or ``hold``)."""
    # a broken settings file: its message, not argparse's "invalid"
    with refused_as(argparse.ArgumentTypeError, ValueError):
        from baselines.agents import AGENTS

    if text != "hold" and text not in AGENTS:
        raise argparse.ArgumentTypeError(
            f"{text[:80]} is not a particle-filter agent (one has a likelihood to replace); "
            f"they are {', '.join(sorted(AGENTS))}"
        )
    return text


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``oracle``."""
    op = add_command(
        subparsers,
        "oracle",
        "each agent's error with its image likelihood and with truth oracles, split",
        "humotion-gym oracle --task BodyTrack-v2 --agents pf-cv pf-mix --declared --episodes 12",
        details="Track each task's episodes with every particle-filter agent, once with its "
        "image likelihood and once with each oracle in its place (the true 2D keypoints with "
        "pixel noise, the same without left/right identity, the true 3D keypoints with noise; "
        "same prior, filter, particles and seeds), and hold once; then split the error into "
        "what better 2D evidence removes, what depth along the ray costs and what the search "
        "loses. Oracles read the truth: this is analysis, never a leaderboard entry "
        "(docs/diagnostics.md).",
    )
    op.add_argument(
        "--task", type=tracked_task, nargs="+", action=Distinct, default=["BodyTrack-v2"],
        metavar="TASK",
        help="task ids (default: BodyTrack-v2)",
    )  # fmt: skip
    op.add_argument(
        "--agents", type=_filter_agent, nargs="+", action=Distinct,
        default=["pf-cv", "pf-tree", "pf-mix"],
        metavar="AGENT", help="particle-filter agents; hold always runs (default: pf-cv pf-tree "
        "pf-mix)",
    )  # fmt: skip
    add_particles(op)
    op.add_argument(
        "--oracles", nargs="+", default=list(DEFAULT_ORACLES), metavar="LIKELIHOOD",
        help="image (the agent's own), 2d, 2d-unlabelled, 3d; a suffix sets one's noise: "
        "2d:2 (pixels), 3d:10mm (mm per axis) (default: image 2d 2d-unlabelled 3d)",
    )  # fmt: skip
    op.add_argument(
        "--noise-px", type=positive_float, default=None, metavar="PX",
        help="noise in pixels of every oracle given without its own (default: 2d 1, "
        "2d-unlabelled 3, 3d 1 at the body's depth)",
    )  # fmt: skip
    op.add_argument(
        "--noise-mm", type=positive_float, nargs="+", default=[], metavar="MM",
        help="also a 3d oracle with this noise per axis in mm, for each value (default: none)",
    )  # fmt: skip
    op.add_argument(
        "--declared", action="store_true",
        help="track each task's declared test windows (the leaderboard's --declared; "
        "--episodes then takes the first N)",
    )  # fmt: skip
    op.add_argument(
        "--episodes", type=episode_count, default=None,
        help="seeded episodes per agent and likelihood, or with --declared the first N windows "
        "(default: 20 seeded, or every declared window)",
    )  # fmt: skip
    add_int(
        op, "--agent-seeds", 1, "agent seeds per agent and likelihood", episode_count, metavar="K"
    )
    op.add_argument(
        "--split", choices=["test", "validation"], default="test",
        help="the test persons, or the validation persons (training persons held out) "
        "(default: test)",
    )  # fmt: skip
    op.add_argument(
        "--set", type=key_setting, nargs="+", action=Settings, default=[], metavar="NAME=VALUE",
        help="override a setting of every agent: fit.NAME its prior's, filter.NAME its "
        "filter's, as humotion-gym select's --grid names them (default: none)",
    )  # fmt: skip
    add_seed(op, "the first episode's seed, the agents' first seed and the oracles' noise seed")
    add_data_dir(op)
    op.add_argument(
        "--out", type=output_dir, default=None, metavar="FOLDER",
        help="write results.json.gz (every episode's numbers) and table.md here (default: "
        "print the table only)",
    )  # fmt: skip
    op.add_argument(
        "--resume", action="store_true",
        help="continue the run --out holds (partial.json.gz, written after each agent and "
        "likelihood): its finished rows are kept, the rest run, with the same numbers as one "
        "run; the arguments must be the run's own (--data-dir: the same folders, however "
        "spelt)",
    )  # fmt: skip
    add_json(op, "print what results.json.gz holds, as JSON, instead of the table")
    op.set_defaults(func=_cmd_oracle)


def _oracles(args: argparse.Namespace) -> list:
    """The likelihoods to run, checked: a usage error names the bad one."""
    from baselines.diagnostics.oracle import OracleSettings
    from baselines.diagnostics.split import parse_oracle

    out = []
    for text in args.oracles:
        with refused_as(UsageError, ValueError, "--oracles: "):
            oracle = parse_oracle(text)
        if oracle is not None and args.noise_px is not None and ":" not in text:
            with refused_as(UsageError, ValueError, "--noise-px: "):
                oracle = OracleSettings(oracle.kind, noise_px=args.noise_px)
        out.append(oracle)
    for mm in args.noise_mm:
        with refused_as(UsageError, ValueError, "--noise-mm: "):
            out.append(OracleSettings("3d", noise_mm=mm))
    labels = ["image" if o is None else o.label for o in out]
    twice = sorted({x for x in labels if labels.count(x) > 1})
    if twice:
        raise UsageError(f"--oracles, --noise-mm: {', '.join(twice)} given twice")
    return out


def run_settings(args: argparse.Namespace) -> dict:
    """The command's settings as plain JSON (what the results file records)."""
    return {
        "command": "humotion-gym oracle", "task": list(args.task), "agents": list(args.agents),
        "particles": args.particles, "oracles": list(args.oracles), "noise_px": args.noise_px,
        "noise_mm": list(args.noise_mm), "declared": args.declared, "episodes": args.episodes,
        "agent_seeds": args.agent_seeds, "split": args.split, "seed": args.seed,
        "data_dir": [str(d) for d in args.data_dir or []],
        **({"set": dict(args.set)} if args.set else {}),
    }  # fmt: skip


def _resume_settings(args: argparse.Namespace) -> dict:
    """What a resumed run must share with the run it continues (``partial.json.gz`` keeps it).

    :func:`run_settings` with the mocap folders as the run reads them, however spelt.
    """
    from baselines.leaderboard.results import data_folders

    return {**run_settings(args), "data_dir": data_folders(env_kwargs(args))}


def _saved_rows(args: argparse.Namespace) -> dict[str, list]:
    """The finished rows per task of the run ``--out`` holds, or none for a new run.

    Raises:
        UsageError: If ``--out`` holds a run (an oracle run without ``--resume``,
            or another command's), or ``--resume`` finds no unfinished run or
            one of other settings.
        CommandError: If the saved run cannot be read.
    """
    if args.resume and args.out is None:
        raise UsageError("--resume: needs --out FOLDER, the run to continue")
    if args.out is None:
        return {}
    held = held_run(args.out)
    if held is None:
        if args.resume:
            raise UsageError(f"--resume: {args.out} holds no oracle run to continue ({PARTIAL})")
        return {}
    what, name = held
    if what == UNFINISHED_ORACLE_RUN and not args.resume:
        raise UsageError(
            f"--out: {args.out} holds an unfinished oracle run ({PARTIAL}); add --resume to "
            "continue it, or choose another folder"
        )
    if not args.resume:
        raise UsageError(
            f"--out: {args.out} already holds {what} ({name}); choose another folder or move "
            "it away"
        )
    if what == ORACLE_RUN:
        raise UsageError(f"--resume: {args.out} holds a finished oracle run ({name})")
    if what != UNFINISHED_ORACLE_RUN:
        raise UsageError(f"--resume: {args.out} holds {what} ({name}), not an oracle run")
    old, rows = _read_partial(args.out / PARTIAL)
    new = _resume_settings(args)
    if isinstance(old.get("data_dir"), list):  # a run saved with the folders as given
        old["data_dir"] = [
            str(Path(d).resolve()) if isinstance(d, str) else d for d in old["data_dir"]
        ]
    differ = sorted(k for k in old.keys() | new.keys() if old.get(k) != new.get(k))
    if differ:
        shown = "; ".join(f"{k}: saved {old.get(k)!r}, given {new.get(k)!r}" for k in differ)
        raise UsageError(
            f"--resume: {args.out} holds a run of other settings ({shown}); give the saved "
            "ones, or start another --out"
        )
    return rows


def _read_partial(path: Path) -> tuple[dict[str, Any], dict[str, list]]:
    """The settings and the finished rows per task of the unfinished run saved in ``path``.

    Raises:
        CommandError: If it cannot be read, or is not what :func:`_save_row` writes.
    """
    from baselines.diagnostics.split import EPISODE_FIELDS

    def is_row(row: Any) -> bool:
        numbers = [row.get(k) for k in (*EPISODE_FIELDS, "x_hold")] if isinstance(row, dict) else []
        return (
            isinstance(row, dict)
            and isinstance(row.get("agent"), str)
            and isinstance(row.get("likelihood"), str)
            and isinstance(row.get("episodes"), list)
            and all(isinstance(e, dict) for e in row["episodes"])
            and isinstance(row.get("error_mm"), (int, float))
            and all(x is None or isinstance(x, (int, float)) for x in numbers)
            and isinstance(row.get("lost_episodes"), int)
        )

    with refused_as(CommandError, (OSError, ValueError), "--resume: "):
        saved = read_json(path)
    settings = saved.get("settings") if isinstance(saved, dict) else None
    rows = saved.get("rows") if isinstance(saved, dict) else None
    if not (
        isinstance(settings, dict)
        and isinstance(rows, dict)
        and all(isinstance(r, list) and all(map(is_row, r)) for r in rows.values())
    ):
        raise CommandError(
            f"--resume: {path}: not a partial oracle run: expected an object of 'settings' "
            "(an object) and 'rows' (each task's list of finished rows, each an object of an "
            "agent, a likelihood, its summary numbers and its 'episodes')"
        )
    return settings, rows


def _cmd_oracle(args: argparse.Namespace) -> int:
    from baselines.diagnostics.split import (
        SettingsError,
        check_agents,
        compact,
        markdown_report,
        run_split,
    )

    if args.declared and args.split == "validation":
        raise UsageError("--declared: the declared windows are the test persons'; drop --split")
    oracles = _oracles(args)
    saved = _saved_rows(args)
    settings = dict(args.set)
    kwargs = env_kwargs(args)
    if args.split == "validation":
        from baselines.experiments.selection import validation_library

        kwargs["library"] = validation_library(kwargs.pop("data_dir", None))
    results = []
    with refused_as(UsageError, SettingsError, "--set: "):
        # every task's agents made first: one a later task refuses stops the run at once
        for task in args.task:
            check_agents(task, args.agents, args.particles, args.seed, kwargs, settings)
    _check_saved_rows(args, saved, oracles, kwargs)
    try:
        for task in args.task:
            rows = saved.setdefault(task, [])
            result = run_split(
                task, args.agents, oracles, args.particles, episodes=args.episodes,
                declared=args.declared, seed=args.seed, agent_seeds=args.agent_seeds,
                env_kwargs=kwargs, settings=settings, done=rows,
                on_row=lambda row, rows=rows: _save_row(args, saved, rows, row),
            )  # fmt: skip
            results.append(result)
    except KeyboardInterrupt as exc:
        where = ""
        if args.out is not None and saved:
            where = (
                f"; the finished rows are saved in {args.out / PARTIAL}; to finish the run, "
                "give the same command with --resume"
            )
        return interrupted(exc, "humotion-gym oracle", where)
    table = markdown_report(results)
    data = {"settings": run_settings(args), "results": [compact(r) for r in results]}
    if args.out is not None:
        write_json_gz(args.out / RESULTS, data)
        write_text_atomically(args.out / "table.md", table)
        (args.out / PARTIAL).unlink(missing_ok=True)
        if not args.json:
            wrote(args.out / RESULTS, "every episode's numbers")
            wrote(args.out / "table.md")
    if args.json:
        print_json(data)
    else:
        print(table, end="")
    return 0


def _check_saved_rows(
    args: argparse.Namespace, saved: dict[str, list], oracles: list, kwargs: dict[str, Any]
) -> None:
    """Refuse saved rows that are not this run's before any task runs (not when theirs starts).

    Raises:
        CommandError: Naming the saved file and the first row that does not fit.
    """
    from baselines.diagnostics.split import check_done

    if not saved:  # a new run
        return
    for task in saved.keys() - set(args.task):
        raise CommandError(
            f"--resume: {args.out / PARTIAL}: holds rows of {task}, which this run does not track"
        )
    with refused_as(CommandError, ValueError, f"--resume: {args.out / PARTIAL}: "):
        for task, rows in saved.items():
            check_done(
                task, rows, args.agents, oracles, args.episodes, args.declared,
                args.agent_seeds, kwargs,
            )  # fmt: skip


def _save_row(args: argparse.Namespace, saved: dict[str, list], rows: list, row: dict) -> None:
    """Add a finished row to ``saved`` and, with ``--out``, save the unfinished run (unrounded)."""
    rows.append(row)
    if args.out is not None:
        write_json_gz(args.out / PARTIAL, {"settings": _resume_settings(args), "rows": saved})
