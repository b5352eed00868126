"""``humotion-gym data``: tabulate, inspect, check and convert motion data.

::

    humotion-gym data table [--data-dir DIR...] [--split train|test] [--json]
    humotion-gym data info PATH... [--summary] [--json]
    humotion-gym data persons [PATH...] [--test SUBJECT...] [--json]
    humotion-gym data convert IN OUT.bvh
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from humotion_gym.cli._common import (
    CommandError,
    UsageError,
    add_command,
    add_data_dir,
    add_fps,
    add_json,
    check_mocap_paths,
    json_text,
    output_file,
)

if TYPE_CHECKING:
    from humotion_gym.mocap.motion import Motion


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``data table|info|persons|convert``."""
    data = add_command(
        subparsers, "data", "motion data: table, info, persons, convert",
        "humotion-gym data info ../shared/mocap --summary",
    )  # fmt: skip
    dsub = data.add_subparsers(dest="data_command", required=True, metavar="COMMAND")

    table = add_command(
        dsub, "table", "the default motion library, one row per clip",
        "humotion-gym data table --data-dir ../shared/mocap --split test",
    )  # fmt: skip
    add_data_dir(table)
    add_fps(table)
    table.add_argument(
        "--split", choices=["train", "test"], default=None,
        help="only the clips of this person split (default: every clip)",
    )  # fmt: skip
    add_json(table, "JSON lines, one per clip, instead of the table")
    table.set_defaults(func=_cmd_data_table)

    info = add_command(
        dsub, "info",
        "per clip: rig and how it was matched, person, split, label, frames, fps, "
        "seconds, retargeting error, T-pose dropped",
        "humotion-gym data info ../shared/mocap/cmu-asfamc/02/02_01.amc",
    )  # fmt: skip
    info.add_argument("paths", nargs="+", metavar="PATH", help="mocap files or folders")
    add_json(info, "JSON lines instead of a table")
    add_fps(info)
    info.add_argument("--summary", action="store_true", help="only totals per data set")
    info.add_argument("--no-cache", action="store_true", help="parse again, ignore the cache")
    info.set_defaults(func=_cmd_data_info)

    persons = add_command(
        dsub, "persons",
        "one row per subject with its skeleton; checks that no test person trains (exit 1)",
        "humotion-gym data persons ../shared/mocap",
    )  # fmt: skip
    persons.add_argument(
        "paths", nargs="*", metavar="PATH",
        help="mocap files or folders (default: $HUMOTION_MOCAP, else synthetic)",
    )  # fmt: skip
    add_json(persons, "one JSON object instead of a table")
    add_fps(persons)
    persons.add_argument(
        "--test", nargs="+", default=None, metavar="SUBJECT",
        help="check this held-out set against the data's skeletons (default: the library's "
        "held-out persons and the packaged test skeletons, as an environment checks)",
    )  # fmt: skip
    persons.set_defaults(func=_cmd_data_persons)

    conv = add_command(
        dsub, "convert", "write a motion as BVH on the cone-body skeleton",
        "humotion-gym data convert synthetic/walk-01 walk.bvh",
    )  # fmt: skip
    conv.add_argument(
        "input", help="a BVH or AMC file, or synthetic/<clip> (see humotion-gym data table)"
    )
    conv.add_argument(
        "output", type=output_file(".bvh"), help="the .bvh to write (another file than input)"
    )
    add_fps(conv)
    conv.set_defaults(func=_cmd_data_convert)


def _cmd_data_table(args: argparse.Namespace) -> int:
    from humotion_gym.mocap.library import default_library

    lib = default_library(args.data_dir or None, fps=args.fps, progress=not args.json)
    if args.split:
        lib = lib.split(args.split)
    if args.json:  # the table's columns, and where each clip came from
        held = lib.held_out
        for m in lib:
            print(json_text({
                "clip": m.clip_id, "dataset": m.dataset, "subject": m.subject,
                "person": m.meta.get("person", m.subject),
                "split": "test" if m.subject in held else "train", "label": m.label,
                "frames": m.n_frames, "fps": m.fps, "seconds": m.duration, "source": m.source,
            }))  # fmt: skip
        return 0
    print(lib.table())
    return 0


def _clip_row(m: Motion, held_out: frozenset[str] = frozenset()) -> dict:
    err = m.retarget_error()
    err = err[np.isfinite(err)]
    return {
        "file": m.source,
        "clip": m.clip_id,
        "dataset": m.dataset,
        "rig": m.meta.get("rig", ""),
        "rig_match": m.meta.get("rig_match", ""),
        "rig_confidence": float(m.meta["rig_confidence"]) if "rig_confidence" in m.meta else None,
        "rig_detail": m.meta.get("rig_summary", ""),
        "tpose": m.meta.get("tpose", ""),
        "subject": m.subject,
        "person": m.meta.get("person", m.subject),
        "split": m.meta.get("split") or ("test" if m.subject in held_out else "train"),
        "split_rule": m.meta.get("split_rule", ""),
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
    if len(lib) == 0:
        raise CommandError(
            f"no BVH or ASF/AMC motion capture under {', '.join(map(str, args.paths))}"
        )
    if args.summary:
        out = {
            ds: {k: v if k in ("clips", "frames") else round(v, 1) for k, v in s.items()}
            for ds, s in library_summary(lib).items()
        }
        if args.json:
            print(json_text(out, indent=2))
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
    rows = [_clip_row(m, lib.held_out) for m in lib]
    if args.json:
        for r in rows:
            print(json_text(r))
        return 0
    head = (f"{'file':40s} {'rig':19s} {'matched':14s} {'person':16s} {'split':5s} "
            f"{'label':10s} {'frames':>6s} {'fps':>4s} {'sec':>6s} {'err':>6s} {'max':>6s}  "
            "t-pose")  # fmt: skip
    print(head)
    for r in rows:
        name = r["file"] if len(r["file"]) <= 40 else "..." + r["file"][-37:]
        matched = f"{r['rig_match']} {r['rig_confidence']:.2f}" if r["rig_match"] else ""
        err_cols = " ".join(
            f"{e:6.1f}" if e is not None else f"{'-':>6s}"
            for e in (r["error_mean_mm"], r["error_max_mm"])
        )
        print(
            f"{name:40s} {r['rig']:19s} {matched:14s} {r['person']:16s} {r['split']:5s} "
            f"{r['label']:10s} {r['frames']:6d} {r['fps']:4.0f} {r['seconds']:6.1f} "
            f"{err_cols}  {r['tpose'] or '-'}"
        )
    weak = [r for r in rows if r["rig_match"] not in ("", "profile")]
    for r in weak:
        print(f"rig of {r['clip']}: {r['rig_detail']}")
    dropped = sum(bool(r["tpose"]) for r in rows)
    rules = "; ".join(lib.split_rules) or "-"
    print(f"{len(rows)} clips; T-pose dropped from {dropped}; split rule(s): {rules}")
    return 0


def _cmd_data_persons(args: argparse.Namespace) -> int:
    from humotion_gym.mocap import library, persons

    if args.paths:
        lib = library.load_library(args.paths, fps=args.fps, progress=not args.json)
    else:
        dirs = library.configured_data_dirs(None)
        if dirs:  # refused as by the commands with --data-dir: never "nothing to compare"
            check_mocap_paths(dirs, f"${library.MOCAP_ENV}")
        lib = library.default_library(None, fps=args.fps, progress=not args.json)
    if args.test:
        unknown = sorted(set(args.test) - set(lib.subjects))
        if unknown:
            raise UsageError(
                f"--test: no subject {', '.join(unknown)} in the data; its subjects are "
                f"{', '.join(lib.subjects[:12])}{' ...' if len(lib.subjects) > 12 else ''}"
            )
    test = frozenset(args.test) if args.test else persons.held_out_subjects(lib)
    groups = persons.skeleton_groups(lib)
    person_of = {m.subject: m.meta.get("person", m.subject) for m in lib}
    group_of = {s: i for i, g in enumerate(groups) for s in g}
    try:
        if args.test:  # a held-out set to try: the data's own skeletons, compared
            report = persons.check_person_split(lib, test)
        else:  # the check an environment on this data runs, packaged test skeletons included
            report = persons.check_data_persons(lib)
        ok, message = True, str(report)
    except persons.SplitError as exc:
        ok, message = False, str(exc) if args.test else _leak_message(exc.pairs, lib.subjects)
    rows: list[dict[str, Any]] = [
        {
            "subject": s.subject,
            "dataset": ",".join(s.datasets),
            "clips": s.clips,
            "frames": s.frames,
            "person": person_of.get(s.subject, s.subject),
            "split": "test" if s.subject in test else "train",
            "signature_mm": {
                n: round(float(v), 2)
                for n, v in zip(persons.SIGNATURE_NAMES, s.signature, strict=True)
            },
            "spread_mm": round(s.spread_mm, 4),
            "group": f"G{group_of[s.subject] + 1}",
            "same_skeleton_as": [o for o in groups[group_of[s.subject]] if o != s.subject],
        }
        for s in persons.subject_skeletons(lib)
    ]
    if args.json:
        print(json_text({
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
    if not ok:  # after the table, which shows the persons at fault
        raise CommandError(message)
    return 0


def _leak_message(pairs: Sequence[tuple[str, str]], subjects: Sequence[str]) -> str:
    """:func:`~humotion_gym.mocap.persons.check_data_persons`'s refusal, said by this command.

    A held-out person absent from the table was matched by the skeleton the
    package records for it, which the message says.
    """
    shown = ", ".join(f"{test} ~ {train}" for test, train in pairs)
    absent = sorted({test for test, _ in pairs} - set(subjects))
    known = f"; {', '.join(absent)}: by the package's record of its skeleton" if absent else ""
    return (
        f"person split fails: a held-out person's skeleton is also a training person's "
        f"({shown}{known}), so an environment on this data refuses it (the test persons "
        "would be trained on); move those clips out or put them on one side"
    )


def _cmd_data_convert(args: argparse.Namespace) -> int:
    from humotion_gym.mocap.export import write_motion_bvh
    from humotion_gym.mocap.library import load_library, synthetic_library

    if args.input.startswith("synthetic/"):
        lib = synthetic_library(fps=args.fps)
        if args.input not in lib.clip_ids:
            raise UsageError(
                f"input: no clip {args.input}; the synthetic clips are "
                f"{', '.join(lib.clip_ids[:6])} ... (see humotion-gym data table)"
            )
        motion = lib[args.input]
    else:
        if not Path(args.input).is_file():
            raise UsageError(
                f"input: expected one BVH or AMC file (or synthetic/<clip>), got {args.input}"
                + (" (a folder)" if Path(args.input).is_dir() else " (no such file)")
            )
        if args.output.exists() and os.path.samefile(args.input, args.output):
            # writing the converted clip over its own source would lose the original
            raise UsageError(
                f"output: {args.output} is the input file {args.input}; write the BVH to "
                "another file"
            )
        lib = load_library([args.input], fps=args.fps, progress=False)
        if len(lib) != 1:
            raise UsageError(f"input: {args.input} holds {len(lib)} clips; convert one")
        motion = lib[0]
    write_motion_bvh(args.output, motion.params, motion.shape, motion.fps)
    print(f"wrote {args.output}: {motion.n_frames} frames at {motion.fps:g} fps ({motion.clip_id})")
    return 0
