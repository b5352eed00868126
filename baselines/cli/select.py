"""``humotion-gym select``: choose likelihood settings by cross-validation on training persons.

::

    humotion-gym select --task ArmTrack-v2 --agent pf-tree --grid sharpness=1,2,3,5
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence

from baselines.cli._args import add_imports, add_particles, agent_name, tracked_task
from humotion_gym.cli._common import (
    MAX_EPISODES,
    UsageError,
    add_command,
    add_data_dir,
    add_int,
    add_json,
    add_seed,
    add_task,
    episode_count,
    int_at_least,
    print_json,
    refused_as,
)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``select``."""
    sel = add_command(
        subparsers,
        "select",
        "choose a likelihood setting by cross-validation on training persons",
        "humotion-gym select --task ArmTrack-v2 --agent pf-tree --grid sharpness=1,2,3,5",
        details="Track the validation persons (training persons held out of the priors' "
        "data) with each candidate value of likelihood settings (or prior settings, fit.NAME, or "
        "the annealed filter's settings, filter.NAME) "
        "and pick the combination with the lowest mean error. Every value is checked before "
        "any episode runs (a fit.NAME by fitting the prior with it). Test persons are never "
        "loaded.",
    )
    add_task(sel, "ArmTrack-v2", kind=tracked_task)
    sel.add_argument(
        "--agent", type=agent_name, default="pf-tree",
        help="particle-filter agent; yours with --import (default: pf-tree)",
    )  # fmt: skip
    add_imports(sel)
    sel.add_argument(
        "--grid", nargs="+", default=["sharpness=1,2,3,5"], metavar="NAME=V1,V2",
        help="candidate values per ObservationModel setting, or per setting of the agent's "
        "prior written fit.NAME (e.g. fit.damping=1,0.5), or of the annealed filter written "
        "filter.NAME (layers, alpha, diffusion, beta_max; e.g. filter.alpha=0.5,0.7); every "
        "combination is tried "
        "(default: sharpness=1,2,3,5)",
    )  # fmt: skip
    add_particles(sel)
    add_int(sel, "--episodes", 20, "episodes per value", episode_count)
    add_seed(sel, "first episode seed")
    sel.add_argument(
        "--validation", nargs="+", default=None, metavar="SUBJECT",
        help="training subjects to hold out (default: experiments.selection.VALIDATION_SUBJECTS)",
    )  # fmt: skip
    sel.add_argument(
        "--still", type=int_at_least(0, MAX_EPISODES), default=0, metavar="N",
        help="also track up to N still episodes of the validation persons (where hold scores "
        "lowest) and choose the lowest mean error among the settings within 2x hold there; "
        "when none is, the lowest error on the still episodes (the output says which rule "
        "chose; default: 0, mean error only)",
    )  # fmt: skip
    add_data_dir(sel)
    add_json(sel)
    sel.set_defaults(func=_cmd_select)


def parse_grid(items: Sequence[str]) -> dict[str, list[float]]:
    """``NAME=V1,V2,...`` items as ``{name: [values]}``.

    Raises:
        UsageError: Naming ``--grid`` and the item, if one is malformed.
    """
    grid: dict[str, list[float]] = {}
    for item in items:
        name, sep, values = item.partition("=")
        name = name.strip()
        if name in grid:
            raise UsageError(f"--grid: {name} given twice; list its values once, V1,V2")
        try:
            numbers = [float(v) for v in values.split(",") if v.strip()]
        except ValueError:
            numbers = []
        if not sep or not name or not numbers or not all(map(math.isfinite, numbers)):
            raise UsageError(f"--grid: expected NAME=V1,V2,... of finite numbers, got {item[:80]}")
        grid[name] = numbers
    return grid


def _cmd_select(args: argparse.Namespace) -> int:
    from baselines.agents import AGENTS
    from baselines.experiments.selection import select_observation_settings, validation_library
    from humotion_gym.errors import MocapFormatError, RigError

    grid = parse_grid(args.grid)
    if args.agent not in AGENTS:  # hold, random and the learned have nothing to select
        raise UsageError(f"--agent: {args.agent}: expected a particle-filter agent (pf-tree...)")
    try:
        lib = validation_library(args.data_dir or None, args.validation)
    except ValueError as exc:  # a subject absent from the training split, or a test person
        if args.validation is None or isinstance(exc, (MocapFormatError, RigError)):
            raise
        raise UsageError(f"--validation: {str(exc).removeprefix('validation_fold: ')}") from None
    with refused_as(UsageError, ValueError):  # a setting, agent or fold these arguments name
        out = select_observation_settings(
            args.task, args.agent, grid, lib, args.particles, args.episodes, args.seed,
            still=args.still,
        )  # fmt: skip
    if args.json:  # with what reruns it
        print_json({**out, "seed": args.seed, "particles": args.particles,
                    "episodes": args.episodes, "data_dir": args.data_dir or None,
                    "validation": args.validation})  # fmt: skip
        return 0
    print(
        f"{out['task']}: {args.agent} at {args.particles} particles, {args.episodes} episodes "
        f"of the validation persons {', '.join(out['validation_subjects'])} "
        f"(priors fitted on the other {out['train_clips']} training clips)"
    )
    still = "still_hold_mm" in out
    print(
        f"{'settings':44s} {'mean error mm':>14s} {'x hold':>7s}"
        + (f" {'still mm':>9s} {'/ hold':>7s}" if still else "")
    )
    for row in out["rows"]:
        text = " ".join(f"{k}={v:g}" for k, v in row["settings"].items())
        line = f"{text:44s} {row['mean_error_mm']:14.1f} {row['hold_ratio']:7.2f}"
        if still:
            line += f" {row['still_error_mm']:9.1f} {row['still_ratio']:7.2f}"
        print(line)
    chosen = " ".join(f"{k}={v:g}" for k, v in out["chosen"].items())
    hold = f"hold: {out['hold_mm']:.1f} mm"
    if still:
        hold += (
            f"; still episodes: {out['still_episodes']}, hold {out['still_hold_mm']:.1f} mm there"
        )
    print(hold)
    print(f"chosen: {chosen} ({out['chosen_by']})")
    return 0
