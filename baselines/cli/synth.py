"""``humotion-gym synth``: synthesise motion from a fitted prior, as BVH (and video).

Every prior is fitted the same way (:func:`baselines.priors.fitting.fit_prior`,
cached) on the training persons' clips and sampled through the signature every
prior shares, ``synthesize_motion(fitted, base_pose, frames, fps, rng)``::

    humotion-gym synth --prior tree --seconds 2 --out synth.bvh [--video synth.mp4]
    humotion-gym synth --prior tree --setting beta=0.05 --out faithful.bvh
"""

from __future__ import annotations

import argparse
import inspect
from collections.abc import Callable
from typing import Any

import numpy as np

from humotion_gym.cli._common import (
    CommandError,
    UsageError,
    add_command,
    add_data_dir,
    add_fps,
    add_int,
    add_seed,
    check_memory,
    float_between,
    output_file,
    refused_as,
    wrote,
)

#: The longest motion ``--seconds`` asks for (an hour).
MAX_SECONDS = 3600.0
#: Bytes a synthesised frame takes while sampled and written (the pose, its
#: keypoints and the prior's state, a few hundred float64 values, with margin).
BYTES_PER_FRAME = 8192

#: Shorter names accepted by ``--prior``.
ALIASES = {"pca": "cyclic_pca", "cv": "constant_velocity"}
#: The tree's temperature (``--beta``): the fit takes any number, but the fitted
#: model divides by it, so 0 fails only after the whole fit.
BETA = float_between(0.0, 1e6, open_low=True)
#: Settings whose values are read by their own argparse type, as ``--setting
#: NAME=VALUE`` and as their own flag alike; the others by :func:`_value`.
SETTING_TYPES: dict[str, Callable[[str], Any]] = {"beta": BETA}


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``synth``."""
    from baselines.priors import PRIORS

    syn = add_command(
        subparsers, "synth", "synthesise motion from a fitted prior, as BVH (and video)",
        "humotion-gym synth --prior tree --seconds 2 --out synth.bvh --video synth.mp4",
    )  # fmt: skip
    names = sorted(PRIORS) + sorted(ALIASES)
    syn.add_argument(
        "--prior", choices=names, default="tree", metavar="PRIOR",
        help=f"the prior to fit and sample: {', '.join(sorted(PRIORS))} "
        "(pca and cv are short for cyclic_pca and constant_velocity; default: tree)",
    )  # fmt: skip
    syn.add_argument(
        "--seconds", type=float_between(0.0, MAX_SECONDS, open_low=True), default=2.0,
        help=f"length of the motion, s, at most {MAX_SECONDS:g} (default: 2)",
    )  # fmt: skip
    syn.add_argument(
        "--labels", nargs="+", default=["walk"], metavar="LABEL",
        help="activities of the training clips the prior is fitted on (default: walk)",
    )  # fmt: skip
    add_int(syn, "--max-clips", 40, "fit on at most this many training clips, a random subset")
    syn.add_argument(
        "--start", default=None,
        help="clip id whose first pose the motion starts from: tree and cv continue that pose; "
        "pca and slds draw their own joint angles from the first frame and keep the rest "
        "(default: the first of the training clips the fit uses: with more than --max-clips, "
        "a subset drawn by --seed)",
    )  # fmt: skip
    syn.add_argument(
        "--setting", nargs="+", default=[], metavar="NAME=VALUE",
        help="settings of the prior's fit, e.g. beta=0.05 for a faithful tree (default: none)",
    )  # fmt: skip
    syn.add_argument(
        "--beta", type=BETA, default=None,
        help="short for --setting beta=BETA, the tree's temperature, a number > 0 (default: "
        "the fit's)",
    )  # fmt: skip
    add_seed(syn)
    syn.add_argument(
        "--out", type=output_file(".bvh"), default="synth.bvh",
        help="the BVH to write (default: synth.bvh)",
    )  # fmt: skip
    syn.add_argument(
        "--video", type=output_file(".mp4", ".avi"), default=None,
        help="also write a video here, .mp4 or .avi (default: none)",
    )  # fmt: skip
    add_data_dir(syn)
    add_fps(syn)
    syn.set_defaults(func=_cmd_synth)


def _value(name: str, text: str, default: Any) -> Any:
    """A setting's value, of the kind its default is: a boolean, a word, else a number >= 0.

    Every numeric setting of the priors' fits is a count, a length or a scale,
    so a negative, infinite or NaN value is refused rather than passed on. A
    word (``replay=velocity``, ``moving=root``) goes to the fit, which names
    the words it takes.
    """
    if name in SETTING_TYPES:
        with refused_as(UsageError, argparse.ArgumentTypeError, f"--setting: {name}: "):
            return SETTING_TYPES[name](text)
    if isinstance(default, str) or (default is None and not _reads_as_number(text)):
        return text
    if isinstance(default, (tuple, list)):  # a list of words (labels=walk,run)
        return tuple(t for t in text.split(",") if t)
    if isinstance(default, bool):
        flag = {"true": True, "false": False}.get(text.lower())
        if flag is None:
            raise UsageError(f"--setting: {name} is true or false, got {text[:40]!r}")
        return flag
    try:
        value = float(text)
    except ValueError:
        raise UsageError(f"--setting: {name} is a number, got {text[:40]!r}") from None
    if not np.isfinite(value) or value < 0:
        raise UsageError(f"--setting: {name} is a finite number >= 0, got {text[:40]!r}")
    if isinstance(default, int) or (default is None and value.is_integer()):
        if not value.is_integer():
            raise UsageError(f"--setting: {name} is a whole number, got {text[:40]!r}")
        return int(value)
    return value


def _reads_as_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def fit_settings(module: Any, items: list[str], beta: float | None) -> dict[str, Any]:
    """``NAME=VALUE`` items (and ``--beta``) as keyword arguments of ``module.fit``.

    Raises:
        UsageError: Naming the flag, for a malformed item or a setting the fit lacks.
    """
    params = inspect.signature(module.fit).parameters
    accepted = set(params) - {"motions", "free", "rng"}
    settings: dict[str, Any] = {}
    for item in items:
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep or not name or not value.strip():
            raise UsageError(f"--setting: expected NAME=VALUE, got {item[:80]}")
        if name in settings:  # the later would replace the earlier without a word
            raise UsageError(f"--setting: {name} given twice")
        default = params[name].default if name in accepted else None
        settings[name] = _value(name, value.strip(), default) if name in accepted else value
    if beta is not None:
        if "beta" in settings:
            raise UsageError("--beta, --setting: beta given twice")
        settings["beta"] = beta
    unknown = sorted(set(settings) - accepted)
    if unknown:
        flag = "--beta" if unknown == ["beta"] and beta is not None else "--setting"
        raise UsageError(
            f"{flag}: the {module.NAME} prior's fit has no setting {', '.join(unknown)}; "
            f"its settings are {', '.join(sorted(accepted))}"
        )
    return settings


def _cmd_synth(args: argparse.Namespace) -> int:
    from baselines.priors.fitting import fit_prior, prior_module
    from humotion_gym.mocap.export import write_motion_bvh
    from humotion_gym.mocap.library import default_library
    from humotion_gym.video import render_motion, write_video

    name = ALIASES.get(args.prior, args.prior)
    module = prior_module(name)
    settings = fit_settings(module, args.setting, args.beta)
    frames = max(2, int(round(args.seconds * args.fps)))
    check_memory("--seconds", frames, BYTES_PER_FRAME, "frames")
    if args.video:  # the rendered frames are held, then written
        check_memory("--seconds", frames, 128 * 128 * 3, "video frames")
    lib = default_library(args.data_dir or None, fps=args.fps)
    clips = list(lib.split("train").filter(labels=args.labels))
    if not clips:
        raise CommandError(f"--labels: no training clip has the labels {', '.join(args.labels)}")
    rng = np.random.default_rng(args.seed)
    if len(clips) > args.max_clips:
        pick = np.sort(rng.choice(len(clips), args.max_clips, replace=False))
        clips = [clips[k] for k in pick]
    if args.start and args.start not in lib.clip_ids:
        raise CommandError(
            f"--start: no clip {args.start} in the library (see humotion-gym data table)"
        )
    start = lib[args.start] if args.start else clips[0]
    _, fitted = fit_prior(module, clips, None, settings)
    params = module.synthesize_motion(fitted, start.params[0], frames, args.fps, rng)
    write_motion_bvh(args.out, params, start.shape, args.fps)
    wrote(args.out, f"{params.shape[0]} frames from the {name} prior, starting at {start.clip_id}")
    if args.video:
        write_video(args.video, render_motion(params, start.shape), fps=args.fps, scale=1)
        wrote(args.video)
    return 0
