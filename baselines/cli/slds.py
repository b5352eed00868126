"""``humotion-gym slds``: the SLDS experiments of Pavlovic, Rehg, Cham & Murphy (1999).

The experiments are in :mod:`baselines.experiments.pavlovic1999`::

    humotion-gym slds classify --train PATH... --test PATH... [--seed S] [--json] [--figure F]
    humotion-gym slds select [--data-dir DIR] [--features F...] [--extra-noise-degs DEG...]
                             [--criterion kinds|frames] [--jobs N] [--json]
    humotion-gym slds splits [--data-dir DIR] [--features F] [--extra-noise-deg DEG]
                             [--training-persons] [--jobs N] [--seed S] [--json]
    humotion-gym slds interpolate [--data-dir DIR] [--json] [--figure F]
    humotion-gym slds figures [--data-dir DIR] [--out-dir DIR]
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from collections.abc import Sequence

import numpy as np

from humotion_gym.body import PARAM_INDEX, PARAM_NAMES
from humotion_gym.cli._common import (
    CommandError,
    Distinct,
    UsageError,
    add_command,
    add_data_dir,
    add_int,
    add_json,
    add_seed,
    float_between,
    int_at_least,
    output_dir,
    output_file,
    print_json,
    probability,
    refused_as,
    wrote,
)
from humotion_gym.mocap.motion import Motion

#: Degrees a noise flag accepts (a joint angle's noise beyond a half turn means nothing).
_DEGREES = float_between(0.0, 180.0)


def _add_model_args(p: argparse.ArgumentParser, figure: bool = True, clips: bool = True) -> None:
    """``--seed``, ``--states``, ``--iters``; ``--max-train-clips`` where the command uses it."""
    from baselines.priors import slds

    add_seed(p, "seed of EM and of the test sequences")
    add_int(
        p, "--states", slds.N_STATES, "switch states per activity, the JSON's states (its "
        "n_states, where given, counts the states fitted in all: every activity's, less any EM "
        "left unused)", int_at_least(1, 64),
    )  # fmt: skip
    add_int(
        p, "--iters", slds.CLASSIFY_N_ITER, "EM iterations per activity", int_at_least(1, 10_000)
    )
    if clips:
        p.add_argument(
            "--max-train-clips", type=int_at_least(1), default=None,
            help="training clips per activity (default: all)",
        )  # fmt: skip
    if figure:
        add_json(p)
        p.add_argument(
            "--figure", type=output_file(".png"), default=None,
            help="also write the figure here, .png (default: none)",
        )  # fmt: skip


def _add_run_args(p: argparse.ArgumentParser, what: str) -> None:
    """``--jobs`` (``what`` run in parallel processes), ``--quiet`` and ``--json``."""
    add_int(p, "--jobs", 1, f"{what} run in parallel processes", int_at_least(1, 256))
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")
    add_json(p)


def features_arg(text: str) -> str:
    """An argparse ``type`` for a feature name (``pavlovic1999.parse_features``)."""
    from baselines.experiments import pavlovic1999 as pav

    with refused_as(argparse.ArgumentTypeError, ValueError):
        pav.parse_features(text)
    return text


def param_name(text: str) -> str:
    """An argparse ``type`` for a pose parameter's name (``r_knee``...)."""
    if text not in PARAM_INDEX:
        raise argparse.ArgumentTypeError(
            f"unknown parameter {text[:40]!r}; the parameters are {', '.join(PARAM_NAMES)}"
        )
    return text


def _add_variant_args(p: argparse.ArgumentParser) -> None:
    """``--features`` and ``--extra-noise-deg`` of one classifier setting."""
    from baselines.experiments import pavlovic1999 as pav

    p.add_argument(
        "--features", type=features_arg, default=pav.CLASSIFY_FEATURES,
        help=f"what the models see: {pav.FEATURES_HELP} (default: {pav.CLASSIFY_FEATURES})",
    )  # fmt: skip
    p.add_argument(
        "--extra-noise-deg", type=_DEGREES, default=pav.CLASSIFY_EXTRA_NOISE_DEG,
        help="measurement noise the decoder assumes on top of the test noise, degrees "
        f"(default: {pav.CLASSIFY_EXTRA_NOISE_DEG:g})",
    )  # fmt: skip


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``slds classify|select|splits|interpolate|figures``."""
    p = add_command(
        subparsers, "slds", "switching linear dynamic system experiments (Pavlovic et al. 1999)",
        "humotion-gym slds figures --data-dir ../shared/mocap --out-dir slds_figures",
    )  # fmt: skip
    sub = p.add_subparsers(dest="slds_command", required=True, metavar="COMMAND")
    _register_classify(sub)
    _register_select(sub)
    _register_splits(sub)
    _register_interpolate(sub)
    _register_figures(sub)


def _register_classify(sub: argparse._SubParsersAction) -> None:
    """Add ``slds classify``."""
    from baselines.experiments import pavlovic1999 as pav

    c = add_command(
        sub, "classify", "walk/run classification (section 4.1, Fig. 3)",
        "humotion-gym slds classify --train ../shared/mocap/cmu-asfamc "
        "--test ../shared/mocap/bandai-1",
    )  # fmt: skip
    c.add_argument(
        "--train", nargs="+", required=True, metavar="PATH", help="training mocap files or folders"
    )
    c.add_argument(
        "--test", nargs="+", required=True, metavar="PATH", dest="test_paths",
        help="test mocap files or folders, none of them also in --train",
    )  # fmt: skip
    c.add_argument(
        "--labels", nargs="+", action=Distinct, default=None,
        help="activities, two or more (default: walk and run, with dash counted as run)",
    )  # fmt: skip
    c.add_argument(
        "--switch-prob", type=probability, default=pav.CLASSIFY_SWITCH_PROB,
        help=f"probability of leaving a switch state (default: {pav.CLASSIFY_SWITCH_PROB:g})",
    )  # fmt: skip
    c.add_argument(
        "--free", nargs="+", type=param_name, action=Distinct, default=None, metavar="PARAM",
        help=f"parameter names to model, each once (default: {' '.join(pav.CLASSIFY_PARAMS)})",
    )  # fmt: skip
    noise = float(np.degrees(pav.NOISE_STD))
    c.add_argument(
        "--noise-deg", type=_DEGREES, default=noise,
        help=f"noise added to the test sequences, degrees (default: {noise:g})",
    )  # fmt: skip
    _add_variant_args(c)
    _add_model_args(c)
    c.set_defaults(func=_cmd_classify)


def _register_select(sub: argparse._SubParsersAction) -> None:
    """Add ``slds select``."""
    from baselines.experiments import pavlovic1999 as pav

    sel = add_command(
        sub, "select", "choose the classifier's settings by cross-validation on the train split",
        "humotion-gym slds select --data-dir ../shared/mocap --jobs 2",
    )  # fmt: skip
    add_data_dir(sel)
    sel.add_argument(
        "--param-sets", nargs="+", default=None, metavar="NAME",
        help=f"candidate parameter subsets (default: all of {', '.join(pav.CANDIDATE_PARAMS)})",
    )  # fmt: skip
    probs = list(pav.CANDIDATE_SWITCH_PROBS)
    sel.add_argument(
        "--switch-probs", nargs="+", type=probability, default=probs, metavar="P",
        help=f"candidate switch probabilities (default: {' '.join(f'{v:g}' for v in probs)})",
    )  # fmt: skip
    sel.add_argument(
        "--features", nargs="+", type=features_arg, default=["angles"], metavar="F",
        help=f"candidate features: {pav.FEATURES_HELP} (default: angles; the variant grid: "
        f"{' '.join(pav.CANDIDATE_FEATURES)})",
    )  # fmt: skip
    sel.add_argument(
        "--extra-noise-degs", nargs="+", type=_DEGREES, default=[0.0], metavar="DEG",
        help="candidate extra measurement noise the decoder assumes, degrees (default: 0; the "
        f"variant grid: {' '.join(f'{v:g}' for v in pav.CANDIDATE_EXTRA_NOISE_DEG)})",
    )  # fmt: skip
    sel.add_argument(
        "--person-folds", action=argparse.BooleanOptionalAction, default=True,
        help="hold out every training person outside Bandai-Namco as a CV fold "
        "(leave-one-person-out; default: on)",
    )  # fmt: skip
    sel.add_argument(
        "--criterion", choices=pav.CV_CRITERIA, default="kinds",
        help="kinds: mean of the style folds' and the person folds' pooled errors; frames: "
        "every held-out frame weighs the same (default: kinds)",
    )  # fmt: skip
    _add_model_args(sel, figure=False, clips=False)  # every fold trains on all its clips
    _add_run_args(sel, "folds")
    sel.set_defaults(func=_cmd_select)


def _register_splits(sub: argparse._SubParsersAction) -> None:
    """Add ``slds splits``."""
    from baselines.experiments import pavlovic1999 as pav

    spl = add_command(
        sub, "splits", "classification error per held-out style and per held-out person",
        "humotion-gym slds splits --data-dir ../shared/mocap --training-persons",
    )  # fmt: skip
    add_data_dir(spl)
    spl.add_argument(
        "--params", nargs="+", type=param_name, action=Distinct, default=None, metavar="PARAM",
        help="also score these parameters (each once) as 'given' (default: only the CV-chosen "
        "and old ones)",
    )  # fmt: skip
    spl.add_argument(
        "--switch-prob", type=probability, default=None,
        help="also score this switch probability as 'given' (default: none)",
    )  # fmt: skip
    spl.add_argument(
        "--features", type=features_arg, default=None,
        help=f"also score these features as 'given': {pav.FEATURES_HELP} (default: none)",
    )  # fmt: skip
    spl.add_argument(
        "--extra-noise-deg", type=_DEGREES, default=None,
        help="also score this extra assumed noise (degrees) as 'given' (default: none)",
    )  # fmt: skip
    spl.add_argument(
        "--training-persons", action="store_true",
        help="also hold out each training person outside Bandai-Namco (CMU 5, 7) in turn "
        "(default: off)",
    )  # fmt: skip
    _add_model_args(spl, figure=False, clips=False)
    _add_run_args(spl, "fits")
    spl.set_defaults(func=_cmd_splits)


def _register_interpolate(sub: argparse._SubParsersAction) -> None:
    """Add ``slds interpolate``."""
    i = add_command(
        sub, "interpolate", "fill a gap of held-out walking (Fig. 6)",
        "humotion-gym slds interpolate --data-dir ../shared/mocap --label walk",
    )  # fmt: skip
    add_data_dir(i)
    i.add_argument("--label", default="walk", help="activity of the clips (default: walk)")
    _add_model_args(i)
    i.set_defaults(func=_cmd_interpolate)


def _register_figures(sub: argparse._SubParsersAction) -> None:
    """Add ``slds figures``."""
    f = add_command(
        sub, "figures", "Figs. 3, 5 and 6 on walk/run data; prints a JSON summary",
        "humotion-gym slds figures --data-dir ../shared/mocap --out-dir slds_figures",
    )  # fmt: skip
    add_data_dir(f)
    f.add_argument(
        "--out-dir", type=output_dir, default="slds_figures",
        help="folder for the PNG files (default: slds_figures)",
    )  # fmt: skip
    _add_model_args(f, figure=False)
    f.set_defaults(func=_cmd_figures)


def _cmd_classify(args: argparse.Namespace) -> int:
    from baselines.experiments import pavlovic1999 as pav

    _check_disjoint(args.train, args.test_paths)
    train, test = pav.split_train_test(
        pav.load_motions(args.train), pav.load_motions(args.test_paths)
    )
    if args.labels is None:  # walk and run, Bandai-Namco set 1's dash as run
        train, test = pav.activity_clips(train), pav.activity_clips(test)
    wanted = args.labels or pav.CLASSIFY_LABELS
    for flag, clips in (("--train", train), ("--test", test)):
        if not any(args.labels is None or m.label in wanted for m in clips):
            raise UsageError(f"{flag}: no clip of the classified activities ({', '.join(wanted)})")
    # a test clip of an activity with no model would be dropped and the error read without it
    shown = {m.label for m in test if args.labels is None or m.label in wanted}
    untrained = sorted(shown - {m.label for m in train})
    if untrained:
        raise UsageError(
            f"--train: no clip of {', '.join(untrained)}, which --test holds: add such clips to "
            "--train or leave them out of --test"
        )
    _check_two_activities(args.labels, sorted({m.label for m in train if m.label in wanted}))
    result = pav.run_classification(
        train, test, np.random.default_rng(args.seed), free=pav.param_indices(args.free),
        labels=args.labels, n_states=args.states, n_iter=args.iters,
        switch_prob=args.switch_prob, noise_std=float(np.radians(args.noise_deg)),
        max_train_clips=args.max_train_clips, features=args.features,
        extra_noise_deg=args.extra_noise_deg,
    )  # fmt: skip
    out = result.summary()
    out.update(
        train_clips=len(train), test_clips=len(test), seed=args.seed,
        params=[PARAM_NAMES[i] for i in result.model.free], features=args.features,
        extra_noise_deg=args.extra_noise_deg, noise_deg=args.noise_deg, n_iter=args.iters,
        states=args.states, switch_prob=args.switch_prob, labels=list(wanted),
        max_train_clips=args.max_train_clips,
    )  # fmt: skip
    if args.figure:
        pav.plot_segmentation(result, args.figure)
    if args.json:
        print_json(out)
    else:
        print(
            f"SLDS classification: error {100 * result.error:.2f}% over {result.n_points} points "
            f"in {result.n_sequences} sequences (paper: 2.9% over 8,312 points)"
        )
        for lab, err in result.per_label_error.items():
            print(f"  {lab:8s} error {100 * err:.2f}%")
        cap = args.max_train_clips
        most = f" (at most {cap} per activity used)" if cap else ""
        print(
            f"  {len(train)} training clips{most}, {len(test)} test clips, "
            f"{result.model.n_states} switch states fitted in all ({args.states} per activity "
            f"asked), fit {result.seconds_fit:.1f} s"
        )
        if args.figure:
            wrote(args.figure)
    return 0


def _check_two_activities(labels: Sequence[str] | None, trained: Sequence[str]) -> None:
    """Refuse fewer than two activities in ``--labels`` or among ``--train``'s (``trained``)."""
    why = "with one activity's model every frame is read as it, an error of 0% that says nothing"
    if labels is not None and len(labels) < 2:
        raise UsageError(f"--labels: classification needs two or more activities, got only "
                         f"{labels[0][:40]}; {why}")  # fmt: skip
    if len(trained) < 2:
        raise UsageError(
            f"--train: clips of {', '.join(trained)} only, among the classified activities; "
            f"classification needs clips of two or more ({why})"
        )


def _check_disjoint(train: Sequence[str], test: Sequence[str]) -> None:
    """Refuse a clip in both ``--train`` and ``--test`` (it would be scored on its own fit)."""
    from humotion_gym.mocap.library import find_clips

    both = sorted(
        {s.path.resolve() for s in find_clips(train)} & {s.path.resolve() for s in find_clips(test)}
    )
    if both:
        raise UsageError(
            f"--test: {len(both)} clip(s) also in --train (e.g. {both[0]}); the test clips "
            "must be others"
        )


def _source(data_dir: Sequence[str] | None) -> str:
    """What the motions came from, for a message: the flag, the variable, or the synthetic set."""
    from humotion_gym.mocap.library import MOCAP_ENV, configured_data_dirs

    if data_dir:
        return "--data-dir"
    return f"${MOCAP_ENV}" if configured_data_dirs(None) else "the synthetic library"


def _train_motions(data_dir: Sequence[str] | None) -> list[Motion]:
    """The training split of the configured library (never a test person)."""
    from baselines.experiments import pavlovic1999 as pav
    from humotion_gym.mocap.library import MotionLibrary

    return list(MotionLibrary(tuple(pav.default_motions(data_dir))).split("train"))


def _param_sets_arg(names: Sequence[str] | None) -> dict[str, Sequence[str]]:
    from baselines.experiments import pavlovic1999 as pav

    if names is None:
        return dict(pav.CANDIDATE_PARAMS)
    unknown = [n for n in names if n not in pav.CANDIDATE_PARAMS]
    if unknown:
        raise UsageError(
            f"--param-sets: unknown {', '.join(unknown)}; "
            f"choose from {', '.join(pav.CANDIDATE_PARAMS)}"
        )
    return {n: pav.CANDIDATE_PARAMS[n] for n in names}


def _log(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


def _cmd_select(args: argparse.Namespace) -> int:
    from baselines.experiments import pavlovic1999 as pav

    train = _train_motions(args.data_dir)
    with refused_as(CommandError, ValueError, f"{_source(args.data_dir)}: "):
        pav.held_out_groups(train, args.person_folds)  # before the folds' fits start
    result = pav.select_classifier_settings(
        train, np.random.default_rng(args.seed), param_sets=_param_sets_arg(args.param_sets),
        switch_probs=args.switch_probs, n_states=args.states, n_iter=args.iters,
        jobs=args.jobs, log=None if args.quiet else _log, features=args.features,
        extra_noise_degs=args.extra_noise_degs, person_folds=args.person_folds,
        criterion=args.criterion,
    )  # fmt: skip
    if args.json:
        print_json({**result.summary(), "seed": args.seed, "states": args.states,
                          "iters": args.iters})  # fmt: skip
    else:
        print(result.table())
        best = result.best
        print(
            f"chosen: {' '.join(best.params)} ({best.name}), features {best.features}, switch "
            f"probability {best.switch_prob:g}, extra noise {best.extra_noise_deg:g} deg; "
            f"{args.criterion} score {100 * result.scores[result.chosen]:.2f}%, CV error "
            f"{100 * result.cv_error[result.chosen]:.2f}%"
        )
    return 0


def _cmd_splits(args: argparse.Namespace) -> int:
    from baselines.experiments import pavlovic1999 as pav

    settings = pav.default_settings()
    flags = ("params", "switch_prob", "features", "extra_noise_deg")
    given = {k: getattr(args, k) for k in flags if getattr(args, k) is not None}
    if given:  # the CV-chosen setting with what the flags give
        params = given["params"] = tuple(given.get("params", pav.CLASSIFY_PARAMS))
        name = pav.setting_name(params)
        settings["given"] = dataclasses.replace(settings["CV-chosen"], name=name, **given)
    motions = pav.default_motions(args.data_dir)
    with refused_as(CommandError, ValueError, f"{_source(args.data_dir)}: "):
        pav.check_splits(motions)  # before the splits' fits start
    rows = pav.evaluate_splits(
        motions, np.random.default_rng(args.seed), settings,
        n_states=args.states, n_iter=args.iters, jobs=args.jobs,
        log=None if args.quiet else _log, training_persons=args.training_persons,
    )  # fmt: skip
    if args.json:
        print_json({"rows": [r.summary() for r in rows], "seed": args.seed,
                          "states": args.states, "iters": args.iters})  # fmt: skip
    else:
        print(pav.splits_table(rows))
        print(
            "CV-chosen: the defaults CLASSIFY_PARAMS/CLASSIFY_SWITCH_PROB (from "
            "`humotion-gym slds select`); old fixed: picked after seeing held-out results"
        )
    return 0


def _cmd_interpolate(args: argparse.Namespace) -> int:
    from baselines.experiments import pavlovic1999 as pav

    motions = pav.default_motions(args.data_dir)
    labels = sorted({m.label for m in motions})
    if args.label not in labels:
        raise UsageError(f"--label: no clip labelled {args.label[:40]}; the labels are "
                         f"{', '.join(labels)}")  # fmt: skip
    train, test = pav.person_split(motions)
    results, mean, _ = pav.run_interpolation(
        train, test, np.random.default_rng(args.seed), label=args.label,
        n_states=args.states, n_iter=args.iters, max_train_clips=args.max_train_clips,
    )  # fmt: skip
    if args.figure:
        pav.plot_interpolation(results[0], pav.slds.SAGITTAL_INDEX, args.figure)
    out = {
        "seed": args.seed,
        "states": args.states,
        "iters": args.iters,
        "label": args.label,
        "max_train_clips": args.max_train_clips,
        "clips": len(results),
        "gap": list(pav.GAP),
        "mean_abs_error_deg": {k: round(v, 3) for k, v in mean.items()},
        "per_clip": [
            {"clip": r.clip, **{k: round(v, 3) for k, v in r.errors.items()}} for r in results
        ],
    }
    if args.json:
        print_json(out)
    else:
        print(
            f"gap frames {pav.GAP[0]}-{pav.GAP[1] - 1} of {len(results)} held-out "
            f"{args.label} clips, "
            "mean absolute joint-angle error (deg):"
        )
        for k, v in mean.items():
            print(f"  {k:9s} {v:6.2f}")
        if args.figure:
            wrote(args.figure)
    return 0


def _cmd_figures(args: argparse.Namespace) -> int:
    from baselines.experiments import pavlovic1999 as pav

    out = args.out_dir
    rng = np.random.default_rng(args.seed)
    train, test = pav.person_split(pav.default_motions(args.data_dir))
    result = pav.run_classification(
        pav.activity_clips(train), pav.activity_clips(test), rng, labels=pav.CLASSIFY_LABELS,
        n_states=args.states, n_iter=args.iters,
        max_train_clips=args.max_train_clips,
    )  # fmt: skip
    out.mkdir(parents=True, exist_ok=True)  # checked writable when parsed
    pav.plot_segmentation(result, out / "slds_fig3_classification.png")
    results, mean, walk = pav.run_interpolation(
        train, test, rng, n_states=args.states, n_iter=args.iters,
        max_train_clips=args.max_train_clips,
    )  # fmt: skip
    pav.plot_interpolation(results[0], walk.free, out / "slds_fig6_interpolation.png")
    poses, switches = pav.slds.synthesize(walk, 300, rng)
    pav.plot_synthesis(poses, switches, walk.free, out / "slds_fig5_synthesis.png", walk.fps)
    names = [f"slds_fig{n}.png" for n in ("3_classification", "5_synthesis", "6_interpolation")]
    summary = {
        "seed": args.seed, "states": args.states, "iters": args.iters,
        "max_train_clips": args.max_train_clips,
        "classification": result.summary(),
        "interpolation_mean_abs_error_deg": mean,
        "figures": [str(out / name) for name in names],  # these, not whatever the folder holds
    }  # fmt: skip
    print_json(summary)
    return 0
