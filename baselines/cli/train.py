"""``humotion-gym train`` and ``learning-curve``: learned trackers (stable-baselines3).

::

    humotion-gym train --algo bc --task BodyTrack-v2 --steps 100000 --seed 0 --out runs/bc-body
    humotion-gym leaderboard --tasks BodyTrack-v2 --agents bc=runs/bc-body/model.zip pf-tree
    humotion-gym learning-curve --task BodyTrack-v2 --algos ppo bc --seeds 0 1 2 --steps 100000
"""

from __future__ import annotations

import argparse
import contextlib
import filecmp
import json
import shutil
import sys
from pathlib import Path

from baselines.cli._args import Settings, key_value, tracked_task
from humotion_gym.cli._common import (
    CommandError,
    UsageError,
    add_command,
    add_data_dir,
    add_int,
    add_json,
    add_seed,
    add_task,
    hold_default_folder,
    int_at_least,
    output_dir,
    output_file,
    print_json,
    refused_as,
    shared_output_dir,
    wrote,
)
from humotion_gym.files import write_atomically

#: The repository's hyperparameter file (RL Baselines3 Zoo format), when present.
DEFAULT_HYPERPARAMS = Path(__file__).resolve().parents[2] / "hyperparams" / "ppo.yml"


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``train`` and ``learning-curve``."""
    tr = add_command(
        subparsers, "train", "train a learned tracker (ppo or bc) on the training persons",
        "humotion-gym train --algo bc --task BodyTrack-v2 --steps 100000 --out runs/bc-body",
    )  # fmt: skip
    tr.add_argument("--algo", choices=["ppo", "bc"], required=True, help="ppo or bc (required)")
    add_task(tr, "BodyTrack-v2", kind=tracked_task)
    add_int(tr, "--steps", 100_000, "environment steps to train for")
    add_seed(tr, "seed of the policy, the episodes and the rollouts")
    tr.add_argument(
        "--out", type=output_dir, default=None,
        help="output folder: model.zip, config.json, checkpoints/, logs/ "
        "(default: runs/ALGO-TASK-sSEED)",
    )  # fmt: skip
    tr.add_argument(
        "--hyperparams", type=Path, default=None,
        help="PPO settings, an RL Baselines3 Zoo YAML file with an entry per task "
        "(default: the repository's hyperparams/ppo.yml when present, else built-in)",
    )  # fmt: skip
    tr.add_argument(
        "--set", type=key_value, nargs="*", action=Settings, default=[], metavar="KEY=VALUE",
        help="override settings, e.g. n_envs=4 rounds=10 (default: none)",
    )  # fmt: skip
    tr.add_argument(
        "--init", type=Path, default=None,
        help="start from this saved policy, e.g. PPO fine-tuning from bc (default: none)",
    )  # fmt: skip
    add_int(tr, "--checkpoint-every", 10_000, "save a checkpoint every this many env steps")
    again = tr.add_mutually_exclusive_group()
    again.add_argument(
        "--resume", action="store_true",
        help="continue the run in OUT (refused where OUT holds none) from its latest "
        "checkpoint, its weights (its episodes start again from the seed: not the "
        "uninterrupted run bit for bit; default: an OUT holding an earlier run's model is "
        "refused)",
    )  # fmt: skip
    again.add_argument(
        "--force", action="store_true",
        help="start afresh over the earlier run in OUT, deleting its model and checkpoints, "
        "and replace the policy --export would write (default: refused)",
    )  # fmt: skip
    tr.add_argument(
        "--no-validation", action="store_true",
        help="track no validation persons (default: tracked every --eval-every steps; they "
        "are never trained on either way)",
    )  # fmt: skip
    add_int(tr, "--eval-every", 10_000, "env steps between two validation runs")
    add_int(tr, "--eval-episodes", 5, "validation episodes per run")
    add_int(tr, "--threads", 1, "torch threads")
    tr.add_argument(
        "--export", type=shared_output_dir, default=None, metavar="DIR",
        help="also copy the model and its config to DIR/ALGO-TASK.zip and .json, as the "
        "pretrained checkpoints in baselines/checkpoints are made; an earlier file there is "
        "refused unless --force, or --resume and it is this run's own export (default: none)",
    )  # fmt: skip
    add_data_dir(tr)
    add_json(tr, "print the run's config.json at the end")
    tr.set_defaults(func=_cmd_train)
    _register_curve(subparsers)


def _register_curve(subparsers: argparse._SubParsersAction) -> None:
    """Add ``learning-curve``."""
    lc = add_command(
        subparsers, "learning-curve",
        "test-split error against env steps for learned trackers (IQM over seeds)",
        "humotion-gym learning-curve --task BodyTrack-v2 --algos ppo bc --seeds 0 1 2",
    )  # fmt: skip
    add_task(lc, "BodyTrack-v2", kind=tracked_task)
    lc.add_argument(
        "--algos", nargs="+", choices=["ppo", "bc"], default=["ppo", "bc"],
        help="algorithms (default: ppo bc)",
    )  # fmt: skip
    lc.add_argument(
        "--seeds", type=int_at_least(0), nargs="+", default=[0, 1, 2],
        help="training seeds, each once: one run each (default: 0 1 2)",
    )  # fmt: skip
    add_int(lc, "--steps", 100_000, "env steps per run")
    add_int(lc, "--points", 5, "checkpoints evaluated per run, evenly spaced")
    add_int(lc, "--episodes", 10, "test episodes per evaluated checkpoint")
    lc.add_argument(
        "--runs-dir", type=output_dir, default="runs/curve",
        help="where the runs are trained, and resumed from: a run found there must be the "
        "same run, of at most --steps (default: runs/curve)",
    )  # fmt: skip
    lc.add_argument(
        "--out", type=output_file(".png"), default="docs/img/rl_learning_curve.png",
        help="figure (PNG); the numbers go beside it as JSON "
        "(default: docs/img/rl_learning_curve.png)",
    )  # fmt: skip
    lc.add_argument(
        "--set", type=key_value, nargs="*", action=Settings, default=[], metavar="KEY=VALUE",
        help="override settings of every run, e.g. n_envs=4 (default: none)",
    )  # fmt: skip
    lc.add_argument(
        "--no-validation", action="store_true",
        help="train without tracking the validation persons (the curve's points are the test "
        "persons' either way; default: tracked every 10,000 env steps, and logged)",
    )  # fmt: skip
    add_data_dir(lc)
    lc.set_defaults(func=_cmd_curve)


def _settings(args: argparse.Namespace) -> dict:
    from baselines.rl import load_hyperparams

    settings: dict = {}
    if args.hyperparams is not None and not args.hyperparams.is_file():
        raise UsageError(f"--hyperparams: {args.hyperparams} is not a file")
    if args.algo == "ppo":
        path = args.hyperparams or (DEFAULT_HYPERPARAMS if DEFAULT_HYPERPARAMS.is_file() else None)
        if path is not None:
            flag = "--hyperparams: " if args.hyperparams is not None else ""
            with refused_as(CommandError, ValueError, flag):
                settings.update(load_hyperparams(path, args.task))
    elif args.hyperparams is not None:
        raise UsageError("--hyperparams: PPO settings; bc takes --set KEY=VALUE")
    settings.update(dict(args.set))
    return settings


def _cmd_train(args: argparse.Namespace) -> int:
    if args.out is not None:  # held by the command line while the command runs
        return _train(args, args.out)
    out = Path("runs") / f"{args.algo}-{args.task}-s{args.seed}"
    with hold_default_folder(out, "out"):  # checked before training and held as --out is
        return _train(args, out)


def _train(args: argparse.Namespace, out: Path) -> int:
    """``train`` into ``out``."""
    from baselines.rl import TrainConfig, train
    from baselines.rl_config import InitMismatch, ResumeMismatch

    with refused_as(UsageError, ValueError):
        config = TrainConfig(
            args.algo, args.task, args.steps, args.seed, str(out),
            data_dir=[str(d) for d in args.data_dir] if args.data_dir else None,
            settings=_settings(args), init=str(args.init) if args.init else None,
            checkpoint_every=args.checkpoint_every, threads=args.threads,
            validation=not args.no_validation, eval_every=args.eval_every,
            eval_episodes=args.eval_episodes,
        )  # fmt: skip
    if args.init is not None and not args.init.exists():
        raise CommandError(f"--init: {args.init} does not exist")
    export = _export_path(args, config.task, out)
    command = "humotion-gym " + " ".join(sys.argv[1:]) if sys.argv[1:] else None
    # With --json, stdout holds the one JSON object: the training log goes to stderr.
    log = contextlib.redirect_stdout(sys.stderr) if args.json else contextlib.nullcontext()
    disagree = (FileExistsError, ResumeMismatch, InitMismatch)  # the arguments disagree
    with refused_as(UsageError, disagree), log:
        path = train(config, resume=args.resume, force=args.force, command=command)
    run_config = json.loads((out / "config.json").read_text())
    if export is not None:
        for source, target in ((path, export), (out / "config.json", export.with_suffix(".json"))):
            write_atomically(target, lambda tmp, s=source: shutil.copyfile(s, tmp))
        if not args.json:
            wrote(export, "the policy (and its config beside it)")
    if args.json:
        print_json(run_config)
        return 0
    print(
        f"{args.algo} on {config.task}: {run_config.get('env_steps')} env steps in "
        f"{run_config.get('wall_s', 0.0):.0f} s"
    )
    wrote(path, f"the policy; score it with --agents {args.algo}={path}")
    return 0


def _export_path(args: argparse.Namespace, task: str, out: Path) -> Path | None:
    """Where ``--export`` copies the policy, checked before the training; None without it.

    An earlier file there is replaced with ``--force``, or with ``--resume`` where it
    is this run's own earlier export (a copy of ``OUT/model.zip``); else a UsageError.
    """
    if args.export is None:
        return None
    export = Path(args.export) / f"{args.algo}-{task}.zip"
    taken = [p for p in (export, export.with_suffix(".json")) if p.exists()]
    own = out / "model.zip"
    if not taken or args.force:
        return export
    if args.resume and export.is_file() and own.is_file() and filecmp.cmp(export, own, False):
        return export
    if args.resume:
        raise UsageError(
            f"--export: {taken[0]} exists and is not this run's model (another run's export, "
            "or a pretrained checkpoint); export into another folder or move it away"
        )
    raise UsageError(
        f"--export: {taken[0]} exists (an earlier export, or a pretrained checkpoint); give "
        "--force to replace it, or export into another folder"
    )


def _cmd_curve(args: argparse.Namespace) -> int:
    from baselines.leaderboard.learning_curve import CurveUsageError, learning_curve

    data_dir = [str(d) for d in args.data_dir] if args.data_dir else None
    with refused_as(UsageError, CurveUsageError):  # raised before any run trains
        result = learning_curve(
            args.task, args.algos, args.seeds, args.steps, args.points, args.episodes,
            args.runs_dir, args.out, data_dir=data_dir, settings=dict(args.set),
            validation=not args.no_validation,
        )  # fmt: skip
    for algo, rows in result["curves"].items():
        for row in rows:
            lo, hi = row["iqm_ci"]
            iqm = row["iqm_mm"]
            print(f"{algo:4s} {row['steps']:>8d} steps  IQM {iqm:.0f} mm ({lo:.0f}-{hi:.0f})")
    print(f"hold: {result['hold_mm']:.0f} mm")
    wrote(args.out, "the learning curve")
    return 0
