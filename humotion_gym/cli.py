"""The ``humotion-gym`` command line.

Sub-commands::

    humotion-gym data table [--data-dir DIR]       the default library, one row per clip
    humotion-gym data info PATH... [--json]        per clip: rig, subject, label, frames,
                                                   fps, seconds, retargeting error
    humotion-gym data persons [PATH...] [--json]   per subject: skeleton signature, group of
                                                   subjects sharing it, train/test; checks
                                                   that no test person trains (exit 1)
    humotion-gym data convert IN OUT.bvh           a motion as BVH on the cone-body skeleton
    humotion-gym download cmu --subjects 2 7 35    CMU ASF/AMC into the download cache
    humotion-gym render --task BodyTrack-v1 --seed 0 --frames 90 --out clip.mp4
                                                   an episode as video and contact sheet
    humotion-gym track --task ArmTrack-v1 --agent pf-tree --particles 300 --episodes 20
                                                   track episodes, errors and timing
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np


def _add_data(sub: argparse._SubParsersAction) -> None:
    data = sub.add_parser("data", help="motion data: list, inspect, convert")
    dsub = data.add_subparsers(dest="data_command", required=True)

    table = dsub.add_parser("table", help="print the default motion library")
    table.add_argument("--data-dir", nargs="*", default=None, help="folders of real mocap")
    table.add_argument("--fps", type=float, default=30.0)
    table.add_argument("--split", choices=["train", "test"], default=None)
    table.set_defaults(func=_cmd_data_table)

    info = dsub.add_parser("info", help="one row per clip with the retargeting error")
    info.add_argument("paths", nargs="+", help="mocap files or folders")
    info.add_argument("--json", action="store_true", help="JSON lines instead of a table")
    info.add_argument("--fps", type=float, default=30.0)
    info.add_argument("--summary", action="store_true", help="only totals per data set")
    info.add_argument("--no-cache", action="store_true", help="parse again, ignore the cache")
    info.set_defaults(func=_cmd_data_info)

    persons = dsub.add_parser(
        "persons", help="one row per subject with its skeleton; checks the person split"
    )
    persons.add_argument(
        "paths", nargs="*", help="mocap files or folders (default: $HUMOTION_MOCAP, else synthetic)"
    )
    persons.add_argument("--json", action="store_true", help="one JSON object instead of a table")
    persons.add_argument("--fps", type=float, default=30.0)
    persons.add_argument(
        "--test", nargs="+", default=None, metavar="SUBJECT",
        help="check this held-out set instead of the library's TEST_SUBJECTS",
    )  # fmt: skip
    persons.set_defaults(func=_cmd_data_persons)

    conv = dsub.add_parser("convert", help="write a motion as BVH on the cone-body skeleton")
    conv.add_argument("input", help="a BVH or AMC file (or 'synthetic/<clip>')")
    conv.add_argument("output", help="the .bvh to write")
    conv.add_argument("--fps", type=float, default=30.0)
    conv.set_defaults(func=_cmd_data_convert)


def _add_download(sub: argparse._SubParsersAction) -> None:
    dl = sub.add_parser("download", help="fetch public motion capture into the cache")
    dsub = dl.add_subparsers(dest="source", required=True)
    cmu = dsub.add_parser("cmu", help="CMU Graphics Lab Motion Capture Database (ASF/AMC)")
    cmu.add_argument(
        "--subjects",
        type=int,
        nargs="+",
        default=None,
        help="CMU subject numbers (required unless --verify)",
    )
    cmu.add_argument("--dest", type=Path, default=None)
    cmu.add_argument("--base-url", default=None)
    cmu.add_argument("--quiet", action="store_true")
    cmu.add_argument("--retries", type=int, default=3, help="attempts per file (default 3)")
    cmu.add_argument(
        "--timeout",
        type=float,
        default=30.0,
        help="socket timeout per connect and per read, s (default 30)",
    )
    cmu.add_argument(
        "--file-deadline",
        type=float,
        default=600.0,
        help="deadline per file or listing, all attempts, s (default 600)",
    )
    cmu.add_argument(
        "--deadline",
        type=float,
        default=7200.0,
        help="deadline for the whole run, s (default 7200)",
    )
    cmu.add_argument(
        "--max-asf-mib", type=float, default=1.0, help="cap on an .asf file, MiB (default 1)"
    )
    cmu.add_argument(
        "--max-amc-mib", type=float, default=64.0, help="cap on an .amc file, MiB (default 64)"
    )
    cmu.add_argument(
        "--max-listing-kib",
        type=float,
        default=1024.0,
        help="cap on a subject's HTML listing, KiB (default 1024)",
    )
    cmu.add_argument(
        "--registry",
        type=Path,
        default=None,
        help="SHA-256 registry file (default: the packaged cmu_sha256.txt)",
    )
    cmu.add_argument(
        "--verify",
        action="store_true",
        help="download nothing; check DEST: verified / unverified / corrupt (exit 1)",
    )
    cmu.set_defaults(func=_cmd_download_cmu)


def _cmd_data_table(args: argparse.Namespace) -> int:
    from humotion_gym.mocap.library import default_library

    lib = default_library(args.data_dir or None, fps=args.fps)
    if args.split:
        lib = lib.split(args.split)
    print(lib.table())
    return 0


def _clip_row(m) -> dict:
    err = m.retarget_error()
    err = err[np.isfinite(err)]
    return {
        "file": m.source,
        "clip": m.clip_id,
        "dataset": m.dataset,
        "rig": m.meta.get("rig", ""),
        "subject": m.subject,
        "label": m.label,
        "frames": m.n_frames,
        "fps": m.fps,
        "seconds": round(m.duration, 3),
        "observed": round(float(m.frame_observed.mean()), 4),
        "error_mean_mm": round(float(err.mean()), 2) if err.size else None,
        "error_max_mm": round(float(err.max()), 2) if err.size else None,
    }


def _cmd_data_info(args: argparse.Namespace) -> int:
    from humotion_gym.mocap.library import library_summary, load_library

    lib = load_library(args.paths, fps=args.fps, use_cache=not args.no_cache)
    if args.summary:
        out = {
            ds: {k: v if k in ("clips", "frames") else round(v, 1) for k, v in s.items()}
            for ds, s in library_summary(lib).items()
        }
        if args.json:
            print(json.dumps(out, indent=2))
        else:
            cols = ("mean", "median", "p95", "max")
            print(
                f"{'data set':12s} {'clips':>6s} {'frames':>8s} "
                + " ".join(f"{c:>6s}" for c in cols)
                + "   (retargeting error, mm)"
            )
            for ds, s in out.items():
                errs = (s[f"error_{c}_mm"] for c in cols)
                print(
                    f"{ds:12s} {s['clips']:6d} {s['frames']:8d} "
                    + " ".join(f"{e:6.1f}" for e in errs)
                )
        return 0
    rows = [_clip_row(m) for m in lib]
    if args.json:
        for r in rows:
            print(json.dumps(r))
        return 0
    head = (f"{'file':48s} {'rig':17s} {'subject':20s} {'label':10s} {'frames':>6s} {'fps':>4s} "
            f"{'sec':>6s} {'err':>6s} {'max':>6s}")  # fmt: skip
    print(head)
    for r in rows:
        name = r["file"] if len(r["file"]) <= 48 else "..." + r["file"][-45:]
        print(
            f"{name:48s} {r['rig']:17s} {r['subject']:20s} {r['label']:10s} {r['frames']:6d} "
            f"{r['fps']:4.0f} {r['seconds']:6.1f} {r['error_mean_mm']:6.1f} "
            f"{r['error_max_mm']:6.1f}"
        )
    return 0


def _cmd_data_persons(args: argparse.Namespace) -> int:
    from humotion_gym.mocap.library import default_library, load_library
    from humotion_gym.mocap.persons import (
        SIGNATURE_NAMES,
        SplitError,
        check_person_split,
        held_out_subjects,
        skeleton_groups,
        subject_skeletons,
    )

    if args.paths:
        lib = load_library(args.paths, fps=args.fps, progress=not args.json)
    else:
        lib = default_library(None, fps=args.fps, progress=not args.json)
    test = frozenset(args.test) if args.test else held_out_subjects(lib)
    groups = skeleton_groups(lib)
    group_of = {s: i for i, g in enumerate(groups) for s in g}
    try:
        report = check_person_split(lib, test)
        ok, message = True, str(report)
    except SplitError as exc:
        ok, message = False, str(exc)
    rows = [
        {
            "subject": s.subject,
            "dataset": ",".join(s.datasets),
            "clips": s.clips,
            "frames": s.frames,
            "split": "test" if s.subject in test else "train",
            "signature_mm": {
                n: round(float(v), 2) for n, v in zip(SIGNATURE_NAMES, s.signature, strict=True)
            },
            "spread_mm": round(s.spread_mm, 4),
            "group": f"G{group_of[s.subject] + 1}",
            "same_skeleton_as": [o for o in groups[group_of[s.subject]] if o != s.subject],
        }
        for s in subject_skeletons(lib)
    ]
    if args.json:
        print(json.dumps({
            "subjects": rows,
            "groups": {f"G{i + 1}": list(g) for i, g in enumerate(groups)},
            "split_ok": ok, "message": message,
        }))  # fmt: skip
    else:
        head = (f"{'dataset':9s} {'subject':22s} {'clips':>5s} {'frames':>6s} {'split':5s} "
                f"{'hip':>5s} {'uparm':>5s} {'forarm':>6s} {'thigh':>5s} {'shin':>5s} "
                f"{'group'}")  # fmt: skip
        print(head + "   (mm; limbs: mean of right and left)")
        for r in rows:
            v = list(r["signature_mm"].values())
            limbs = (0.5 * (v[k] + v[k + 1]) for k in (1, 3, 5, 7))
            size = len(r["same_skeleton_as"]) + 1
            print(
                f"{r['dataset']:9s} {r['subject']:22s} {r['clips']:5d} {r['frames']:6d} "
                f"{r['split']:5s} {v[0]:5.0f} "
                + " ".join(f"{x:5.0f}" for x in limbs)
                + f"  {r['group']}"
                + (f" ({size})" if size > 1 else "")
            )
        for i, g in enumerate(groups):
            if len(g) > 1:
                print(f"G{i + 1}, one skeleton: {', '.join(g)}")
        if ok:
            print(message)
    if not ok:
        print(f"humotion-gym: error: {message}", file=sys.stderr)
        return 1
    return 0


def _cmd_data_convert(args: argparse.Namespace) -> int:
    from humotion_gym.mocap.export import write_motion_bvh
    from humotion_gym.mocap.library import load_library, synthetic_library

    if args.input.startswith("synthetic/"):
        motion = synthetic_library(fps=args.fps)[args.input]
    else:
        lib = load_library([args.input], fps=args.fps, progress=False)
        motion = lib[0]
    write_motion_bvh(args.output, motion.params, motion.shape, motion.fps)
    print(f"wrote {args.output}: {motion.n_frames} frames at {motion.fps:g} fps ({motion.clip_id})")
    return 0


def _cmd_download_cmu(args: argparse.Namespace) -> int:
    from humotion_gym.mocap import download

    if args.verify:
        report = download.verify_cache(args.dest, registry=args.registry)
        print(report.summary())
        return 0 if report.ok else 1
    if not args.subjects:
        raise ValueError("download cmu: --subjects is required (or --verify)")
    mib = 1 << 20
    kwargs = {
        "dest": args.dest,
        "progress": not args.quiet,
        "retries": args.retries,
        "timeout": args.timeout,
        "file_deadline_s": args.file_deadline,
        "deadline_s": args.deadline,
        "max_bytes": {
            ".asf": max(int(args.max_asf_mib * mib), 1),
            ".amc": max(int(args.max_amc_mib * mib), 1),
        },
        "max_listing_bytes": max(int(args.max_listing_kib * 1024), 1),
        "registry": args.registry,
    }
    if args.base_url:
        kwargs["base_url"] = args.base_url
    files = download.download_cmu(args.subjects, **kwargs)
    print(f"{len(files)} files in {files[0].parent.parent if files else args.dest}")
    return 0


def _add_envs(sub: argparse._SubParsersAction) -> None:
    rend = sub.add_parser("render", help="render an episode of a task as video and contact sheet")
    rend.add_argument("--task", default="BodyTrack-v1")
    rend.add_argument("--seed", type=int, default=0)
    rend.add_argument("--frames", type=int, default=90)
    rend.add_argument("--out", type=Path, default=Path("clip.mp4"), help=".mp4 or .avi")
    rend.add_argument(
        "--sheet", type=Path, default=None, help="contact sheet PNG (default: OUT.png)"
    )
    rend.add_argument("--scale", type=int, default=2, help="pixel scale of the video")
    rend.add_argument("--data-dir", nargs="*", default=None)
    rend.add_argument("--size", default=None, help="WIDTHxHEIGHT, e.g. 256x256")
    rend.set_defaults(func=_cmd_render)

    track = sub.add_parser("track", help="track episodes with a particle-filter agent")
    track.add_argument("--task", default="ArmTrack-v1")
    track.add_argument("--agent", default="pf-cv")
    track.add_argument("--particles", type=int, default=300)
    track.add_argument("--episodes", type=int, default=20)
    track.add_argument("--seed", type=int, default=0)
    track.add_argument("--clip", default=None, help="a mocap file or clip id to track")
    track.add_argument("--video", type=Path, default=None, help="video of the first episode")
    track.add_argument("--json", action="store_true")
    track.add_argument("--data-dir", nargs="*", default=None)
    track.set_defaults(func=_cmd_track)


def _add_select(sub: argparse._SubParsersAction) -> None:
    sel = sub.add_parser(
        "select",
        help="choose a likelihood setting by cross-validation on training persons",
        description="Track the validation persons (training persons held out of the priors' "
        "data) with each candidate value of one ObservationModel setting and pick the value "
        "with the lowest mean error. Test persons are never loaded.",
    )
    sel.add_argument("--task", default="ArmTrack-v1", help="task id (default: ArmTrack-v1)")
    sel.add_argument("--agent", default="pf-tree", help="particle-filter agent (default: pf-tree)")
    sel.add_argument(
        "--grid", nargs="+", default=["sharpness=1,2,3,5"], metavar="NAME=V1,V2",
        help="candidate values per ObservationModel setting; every combination is tried "
        "(default: sharpness=1,2,3,5)",
    )  # fmt: skip
    sel.add_argument("--particles", type=int, default=300, help="particles (default: 300)")
    sel.add_argument("--episodes", type=int, default=20, help="episodes per value (default: 20)")
    sel.add_argument("--seed", type=int, default=0, help="first episode seed (default: 0)")
    sel.add_argument(
        "--validation", nargs="+", default=None,
        help="training subjects to hold out (default: experiments.selection.VALIDATION_SUBJECTS)",
    )  # fmt: skip
    sel.add_argument("--data-dir", nargs="*", default=None, help="mocap folders")
    sel.add_argument("--json", action="store_true", help="print JSON")
    sel.set_defaults(func=_cmd_select)


def _parse_grid(items: Sequence[str]) -> dict[str, list[float]]:
    grid: dict[str, list[float]] = {}
    for item in items:
        name, sep, values = item.partition("=")
        try:
            grid[name.strip()] = [float(v) for v in values.split(",") if v.strip()]
        except ValueError:
            sep = ""
        if not sep or not name.strip() or not grid.get(name.strip()):
            raise ValueError(f"--grid: expected NAME=V1,V2,... with numbers, got {item!r}")
    return grid


def _cmd_select(args: argparse.Namespace) -> int:
    from humotion_gym.experiments.selection import select_observation_settings, validation_library

    if args.particles < 1:
        raise ValueError(f"--particles: expected at least 1, got {args.particles}")
    if args.episodes < 1:
        raise ValueError(f"--episodes: expected at least 1, got {args.episodes}")
    grid = _parse_grid(args.grid)
    lib = validation_library(args.data_dir or None, args.validation)
    out = select_observation_settings(
        args.task, args.agent, grid, lib, args.particles, args.episodes, args.seed
    )
    if args.json:
        print(json.dumps(out))
        return 0
    print(
        f"{out['task']}: {args.agent} at {args.particles} particles, {args.episodes} episodes "
        f"of the validation persons {', '.join(out['validation_subjects'])} "
        f"(priors fitted on the other {out['train_clips']} training clips)"
    )
    print(f"{'settings':44s} {'mean error mm':>14s} {'x hold':>7s}")
    for row in out["rows"]:
        text = " ".join(f"{k}={v:g}" for k, v in row["settings"].items())
        print(f"{text:44s} {row['mean_error_mm']:14.1f} {row['hold_ratio']:7.2f}")
    chosen = " ".join(f"{k}={v:g}" for k, v in out["chosen"].items())
    print(f"hold: {out['hold_mm']:.1f} mm; chosen: {chosen}")
    return 0


def _add_discrimination(sub: argparse._SubParsersAction) -> None:
    dis = sub.add_parser(
        "discrimination",
        help="how far the likelihood separates the true pose from poses a few cm off",
    )
    dis.add_argument("--task", default="ArmTrack-v1", help="task id (default: ArmTrack-v1)")
    dis.add_argument("--episodes", type=int, default=20, help="seeded episodes (default: 20)")
    dis.add_argument("--seed", type=int, default=0, help="first episode seed (default: 0)")
    dis.add_argument(
        "--distances", type=float, nargs="+", default=[50.0, 100.0, 200.0],
        help="error bins' centres in mm (default: 50 100 200)",
    )  # fmt: skip
    dis.add_argument("--data-dir", nargs="*", default=None, help="mocap folders")
    dis.add_argument("--json", action="store_true", help="print JSON")
    dis.set_defaults(func=_cmd_discrimination)


def _cmd_discrimination(args: argparse.Namespace) -> int:
    import gymnasium as gym

    from humotion_gym.envs import get_task
    from humotion_gym.experiments.discrimination import (
        likelihood_discrimination,
        likelihood_peak_error,
    )

    if args.episodes < 1:
        raise ValueError(f"--episodes: expected at least 1, got {args.episodes}")
    task = get_task(args.task)
    env = gym.make(f"humotion_gym/{task.name}", terminate_on_lost=False, **_env_kwargs(args))
    out = likelihood_discrimination(env, args.episodes, args.seed, args.distances)
    out["peak"] = likelihood_peak_error(env, args.episodes, args.seed)
    if args.json:
        print(json.dumps(out))
        return 0
    print(
        f"{task.name}: log-likelihood of the true pose minus that of perturbed poses, "
        f"{out['frames']} frames of {args.episodes} episodes"
    )
    print(f"{'error mm':>9s} {'pairs':>7s} {'mean nats':>10s} {'median':>7s} {'truth wins':>11s}")
    for b in out["bins"]:
        print(
            f"{b['distance_mm']:9.0f} {b['pairs']:7d} {b['mean_gap_nats']:10.2f} "
            f"{b['median_gap_nats']:7.2f} {100 * b['truth_wins']:10.1f}%"
        )
    peak = out["peak"]
    print(
        f"among 2,000 poses drawn within 1.2 rad of the truth ({peak['frames']} frames): "
        f"typical error {peak['typical_mm']:.0f} mm, the likelihood's peak "
        f"{peak['peak_mm']:.0f} mm, its weighted mean {peak['weighted_mm']:.0f} mm"
    )
    return 0


def _add_leaderboard(sub: argparse._SubParsersAction) -> None:
    lb = sub.add_parser("leaderboard", help="agents x tasks x particle counts x seeded episodes")
    lb.add_argument("--tasks", nargs="+", default=["ArmTrack-v1", "BodyTrack-v1"])
    lb.add_argument("--agents", nargs="+", default=["pf-cv", "pf-tree"])
    lb.add_argument("--particles", type=int, nargs="+", default=[300, 3000])
    lb.add_argument("--episodes", type=int, default=20)
    lb.add_argument("--seed", type=int, default=0)
    lb.add_argument("--data-dir", nargs="*", default=None)
    lb.add_argument("--out", type=Path, default=None, help="JSON with every episode")
    lb.add_argument("--background", default=None, help="flat or clutter (difficulty)")
    lb.add_argument("--noise", type=float, default=None, help="sensor noise (difficulty)")
    lb.set_defaults(func=_cmd_leaderboard)


def _cmd_leaderboard(args: argparse.Namespace) -> int:
    from baselines.leaderboard import markdown_table, run_leaderboard, save, validity_lines

    kwargs = _env_kwargs(args)
    if args.background:
        kwargs["background"] = args.background
    if args.noise is not None:
        kwargs["noise"] = args.noise
    rows = run_leaderboard(
        args.tasks, args.agents, args.particles, args.episodes, args.seed, kwargs
    )
    if args.out:
        save(rows, args.out)
    print(markdown_table(rows))
    for line in validity_lines(rows):
        print(line)
    return 0


def _add_synth(sub: argparse._SubParsersAction) -> None:
    syn = sub.add_parser("synth", help="synthesise motion from a fitted prior, as BVH")
    syn.add_argument("--prior", choices=["tree", "slds", "pca"], default="tree")
    syn.add_argument("--seconds", type=float, default=2.0)
    syn.add_argument("--start", default=None, help="clip id whose first frames start the motion")
    syn.add_argument("--beta", type=float, default=0.05, help="tree temperature (low: faithful)")
    syn.add_argument("--seed", type=int, default=0)
    syn.add_argument("--out", type=Path, default=Path("synth.bvh"))
    syn.add_argument("--video", type=Path, default=None, help="also write a video")
    syn.add_argument("--data-dir", nargs="*", default=None)
    syn.add_argument("--fps", type=float, default=30.0)
    syn.set_defaults(func=_cmd_synth)


def _cmd_synth(args: argparse.Namespace) -> int:
    from humotion_gym.body import N_PARAMS, standing_pose
    from humotion_gym.mocap.export import write_motion_bvh
    from humotion_gym.mocap.library import default_library
    from humotion_gym.video import render_motion, write_video

    lib = default_library(args.data_dir or None, fps=args.fps)
    train = lib.split("train")
    rng = np.random.default_rng(args.seed)
    frames = max(2, int(round(args.seconds * args.fps)))
    if args.start:
        start_motion = lib[args.start]
    else:
        walks = train.filter(labels=["walk"])
        start_motion = (walks if len(walks) else train)[0]
    shape = start_motion.shape
    free = np.arange(N_PARAMS)
    if args.prior == "tree":
        from humotion_gym.priors import tree

        fitted = tree.fit(train.motions, free=free, rng=rng)
        window = fitted.window + 1
        if start_motion.n_frames < window:
            raise ValueError(f"{start_motion.clip_id}: needs at least {window} frames to start")
        history = start_motion.params[:window]
        params = np.vstack([history, tree.synthesize(fitted, history, frames, args.beta, rng)])
    elif args.prior == "pca":
        from humotion_gym.priors import cyclic_pca

        walks = train.filter(labels=["walk"])
        fitted = cyclic_pca.fit(walks.motions, free=free, rng=rng)
        params = cyclic_pca.synthesize_motion(fitted, standing_pose(shape), frames, args.fps, rng)
    else:
        from humotion_gym.priors import slds_tasks

        params = slds_tasks.synthesize_walk(train, frames, args.fps, rng, shape)
    write_motion_bvh(args.out, params, shape, args.fps)
    print(f"wrote {args.out}: {params.shape[0]} frames from the {args.prior} prior")
    if args.video:
        write_video(args.video, render_motion(params, shape), fps=args.fps, scale=1)
        print(f"wrote {args.video}")
    return 0


def _env_kwargs(args: argparse.Namespace) -> dict:
    kwargs: dict = {}
    if args.data_dir:
        kwargs["data_dir"] = args.data_dir
    if getattr(args, "size", None):
        w, h = (int(v) for v in args.size.lower().split("x"))
        kwargs.update(width=w, height=h)
    return kwargs


def _cmd_render(args: argparse.Namespace) -> int:
    import gymnasium as gym
    from tqdm.auto import tqdm

    from humotion_gym.envs import get_task
    from humotion_gym.video import contact_sheet, write_png, write_video

    task = get_task(args.task)
    env = gym.make(
        f"humotion_gym/{task.name}", episode_frames=args.frames, terminate_on_lost=False,
        **_env_kwargs(args),
    )  # fmt: skip
    base = env.unwrapped
    obs, info = env.reset(seed=args.seed)
    frames = [obs]
    for _ in tqdm(range(args.frames - 1), desc=f"rendering {task.name}", unit="frame"):
        obs, *_ = env.step(base.pose_to_action(base._truth()))
        frames.append(obs)
    write_video(args.out, frames, fps=info["fps"], scale=args.scale)
    sheet = args.sheet or args.out.with_suffix(".png")
    write_png(sheet, contact_sheet(frames, columns=6, count=6))
    print(f"wrote {args.out} ({len(frames)} frames of {info['clip_id']}) and {sheet}")
    return 0


def _cmd_track(args: argparse.Namespace) -> int:
    import gymnasium as gym

    from baselines.agents import make
    from baselines.evaluation import evaluate, run_episode, summarize
    from humotion_gym.envs import get_task
    from humotion_gym.video import write_video

    task = get_task(args.task)
    render_mode = "rgb_array" if args.video else None
    env = gym.make(
        f"humotion_gym/{task.name}", terminate_on_lost=False, render_mode=render_mode,
        **_env_kwargs(args),
    )  # fmt: skip
    agent = make(args.agent, env, n_particles=args.particles, seed=args.seed)
    options = None
    if args.clip:
        options = {"file": args.clip} if Path(args.clip).exists() else {"clip_id": args.clip}
    results = evaluate(agent, env, args.episodes, seed=args.seed, options=options, progress=True)
    if args.video:
        frames: list = []
        run_episode(agent, env, args.seed, options, on_frame=lambda f, i: frames.append(f))
        write_video(args.video, frames, fps=env.unwrapped.metadata["render_fps"])
    summary = summarize(results)
    if args.json:
        print(json.dumps({
            "task": task.name, "agent": args.agent, "particles": args.particles,
            "episodes": [r.to_dict() for r in results], "summary": summary,
        }))  # fmt: skip
        return 0
    print(f"{task.name}  {args.agent}  {args.particles} particles")
    print(
        f"{'seed':>5s} {'clip':28s} {'mean mm':>8s} {'final mm':>9s} "
        f"{'lost at':>8s} {'ms/frame':>9s}"
    )
    for r in results:
        lost = "-" if r.lost_frame is None else str(r.lost_frame)
        print(f"{r.seed:5d} {r.clip_id[:28]:28s} {r.mean_error_mm:8.1f} {r.final_error_mm:9.1f} "
              f"{lost:>8s} {r.ms_per_frame:9.2f}")  # fmt: skip
    lo, hi = summary["mean_error_ci"]
    llo, lhi = summary["lost_fraction_ci"]
    print(
        f"mean error {summary['mean_error_mm']:.1f} mm (95% CI {lo:.1f}-{hi:.1f}), "
        f"IQM {summary['iqm_error_mm']:.1f} mm, lost {summary['lost_fraction']:.0%} "
        f"(95% CI {llo:.0%}-{lhi:.0%}), {summary['ms_per_frame']:.2f} ms/frame"
    )
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``humotion-gym``."""
    parser = argparse.ArgumentParser(
        prog="humotion-gym",
        description="Gymnasium environments for monocular 3D human pose tracking.",
    )
    sub = parser.add_subparsers(dest="command", required=True)
    _add_data(sub)
    _add_download(sub)
    _add_envs(sub)
    _add_leaderboard(sub)
    _add_select(sub)
    _add_discrimination(sub)
    _add_synth(sub)
    from humotion_gym.priors.cyclic_pca import register_cli as _add_pca
    from humotion_gym.priors.slds_tasks import register_cli as _add_slds
    from humotion_gym.priors.tree_figures import register_cli as _add_tree_figures

    _add_tree_figures(sub)
    _add_pca(sub)
    _add_slds(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``humotion-gym`` console script."""
    parser = build_parser()
    args = parser.parse_args(argv)
    # The hot loops multiply small matrices many times; a multi-threaded BLAS
    # spends longer waking its threads than computing (6 times slower per
    # tracked frame on 2 cores). The user's OPENBLAS_NUM_THREADS still wins.
    if "OPENBLAS_NUM_THREADS" not in os.environ and "OMP_NUM_THREADS" not in os.environ:
        from threadpoolctl import threadpool_limits

        threadpool_limits(limits=1, user_api="blas")
    try:
        return int(args.func(args) or 0)
    except ModuleNotFoundError as exc:
        extra = {"matplotlib": "plots", "moviepy": "video", "stable_baselines3": "rl"}
        hint = extra.get(str(exc.name).split(".")[0])
        more = f"; install it with: pip install -e '.[{hint}]'" if hint else ""
        print(f"humotion-gym: error: {exc}{more}", file=sys.stderr)
        return 2
    except (ValueError, FileNotFoundError, KeyError) as exc:
        print(f"humotion-gym: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
