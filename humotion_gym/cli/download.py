"""``humotion-gym download``: fetch public motion capture into the download cache.

::

    humotion-gym download cmu --subjects 2 7 35 [--dest DIR]
    humotion-gym download cmu --activity walk [run ...] --persons 10 [--train-only]
    humotion-gym download cmu --verify [--dest DIR]
"""

from __future__ import annotations

import argparse
from collections import Counter
from pathlib import Path
from urllib.parse import urlsplit

from humotion_gym.cli._common import (
    Distinct,
    UsageError,
    add_command,
    add_int,
    float_between,
    hold_default_folder,
    int_at_least,
    positive_int,
    shared_output_dir,
)

#: URL schemes ``--base-url`` accepts (a mirror on a web server or a local folder).
URL_SCHEMES = ("http", "https", "file")
#: The time limits and size caps of a download, each a number > 0: its flag, the
#: largest value it takes, its default and what it limits.
_LIMITS: tuple[tuple[str, float, float, str], ...] = (
    ("--timeout", 3600.0, 30.0, "socket timeout per connect and per read, s"),
    ("--file-deadline", 86400.0, 600.0, "deadline per file or listing, all attempts, s"),
    ("--deadline", 604800.0, 7200.0, "deadline for the whole run, s"),
    ("--max-asf-mib", 64.0, 1.0, "cap on an .asf file, MiB"),
    ("--max-amc-mib", 4096.0, 64.0, "cap on an .amc file, MiB"),
    ("--max-listing-kib", 65536.0, 1024.0, "cap on a subject's HTML listing, KiB"),
)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``download cmu``."""
    dl = add_command(
        subparsers, "download", "fetch public motion capture into the cache",
        "humotion-gym download cmu --subjects 2 7 35",
    )  # fmt: skip
    dsub = dl.add_subparsers(dest="source", required=True, metavar="SOURCE")
    cmu = add_command(
        dsub, "cmu", "CMU Graphics Lab Motion Capture Database (ASF/AMC)",
        "humotion-gym download cmu --activity walk --persons 10 --dry-run",
    )  # fmt: skip
    cmu.add_argument(
        "--subjects", type=int_at_least(1, 999), nargs="+", action=Distinct, default=None,
        metavar="N",
        help="CMU subject numbers (required unless --activity or --verify)",
    )  # fmt: skip
    cmu.add_argument(
        "--activity", nargs="+", action=Distinct, default=None, metavar="LABEL",
        help="choose subjects who did these activities (walk, run, jump, dance, fight, sports, "
        "acrobatics, reach, everyday, pantomime, calibration, other), most trials first, one "
        "per person (default: none)",
    )  # fmt: skip
    cmu.add_argument(
        "--persons", type=positive_int, default=None,
        help="with --activity: how many persons (default: all who did it)",
    )  # fmt: skip
    cmu.add_argument(
        "--train-only", action="store_true",
        help="with --activity: leave out the benchmark's test persons (default: include them)",
    )  # fmt: skip
    cmu.add_argument(
        "--dry-run",
        action="store_true",
        help="print the chosen subjects with their labels and persons, download nothing",
    )
    cmu.add_argument(
        "--dest", type=shared_output_dir, default=None,
        help="folder to download into (default: the download cache, see humotion-gym cache info)",
    )  # fmt: skip
    cmu.add_argument(
        "--base-url",
        default=None,
        help="mirror of the CMU site, an http(s):// or file:// URL (default: the CMU site)",
    )
    cmu.add_argument("--quiet", action="store_true", help="no progress bar")
    add_int(cmu, "--retries", 3, "attempts per file, 1 to 100", int_at_least(1, 100))
    for flag, high, default, what in _LIMITS:
        cmu.add_argument(
            flag, type=float_between(0.0, high, open_low=True), default=default,
            help=f"{what} (default: {default:g})",
        )  # fmt: skip
    cmu.add_argument(
        "--registry", type=Path, default=None,
        help="SHA-256 registry file (default: the packaged cmu_sha256.txt)",
    )  # fmt: skip
    cmu.add_argument(
        "--verify", action="store_true",
        help="download nothing; check DEST's files (only --subjects' if given): verified / "
        "unverified / corrupt or missing (exit 1)",
    )  # fmt: skip
    cmu.set_defaults(func=_cmd_download_cmu)


#: The flags that choose what to download, which ``--verify`` has no use for.
_CHOICE_FLAGS = ("activity", "persons", "train_only", "dry_run")


def _cmd_download_cmu(args: argparse.Namespace) -> int:
    from humotion_gym.mocap import download
    from humotion_gym.mocap.cmu import CMU_TEST_PERSONS, cmu_index, cmu_person
    from humotion_gym.mocap.labels import ACTIVITY_LABELS

    if args.verify:
        choosing = [f"--{k.replace('_', '-')}" for k in _CHOICE_FLAGS if getattr(args, k)]
        if choosing:  # they choose what to download; --verify downloads nothing
            raise UsageError(f"--verify: checks --subjects or the whole folder; drop {choosing[0]}")
        report = download.verify_cache(args.dest, registry=args.registry, subjects=args.subjects)
        print(report.summary())
        return 0 if report.ok else 1
    if args.base_url is not None:
        _check_url(args.base_url)
    subjects = list(args.subjects or [])
    if subjects:
        known = set(cmu_index().subjects)
        unknown = [s for s in subjects if s not in known]
        if unknown:
            raise UsageError(
                f"--subjects: CMU has no subject {', '.join(map(str, unknown))} "
                f"(its subjects are {min(known)} to {max(known)}, with gaps)"
            )
    if args.activity:
        unknown = sorted(set(args.activity) - set(ACTIVITY_LABELS))
        if unknown:
            raise UsageError(
                f"--activity: no label {', '.join(unknown)}; the labels are "
                f"{', '.join(ACTIVITY_LABELS)}"
            )
        if args.train_only:  # a test person asked for by number would be downloaded anyway
            held = [s for s in subjects if cmu_person(s) in CMU_TEST_PERSONS]
            if held:
                raise UsageError(
                    f"--subjects: {', '.join(map(str, held))} is a test person of the "
                    "benchmark; --train-only leaves test persons out"
                )
        chosen = download.choose_cmu_subjects(args.activity, args.persons, not args.train_only)
        subjects += [s for s in chosen if s not in subjects]
    elif args.persons is not None or args.train_only:
        raise UsageError("--persons and --train-only choose by --activity; give --activity")
    if not subjects:
        raise UsageError("--subjects or --activity is required (or --verify)")
    if args.activity or args.dry_run:
        _print_choice(subjects, args.activity)
    if args.dry_run:
        return 0
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
        "base_url": args.base_url or download.CMU_BASE_URL,
    }
    # Held while downloading only (--dry-run and --verify write nothing), the
    # default download folder as --dest: two downloads share one manifest.
    with hold_default_folder(download.cmu_download_dir(args.dest), "dest"):
        files = download.download_cmu(subjects, **kwargs)
    print(f"{len(files)} files in {files[0].parent.parent if files else args.dest}")
    return 0


def _check_url(url: str) -> None:
    """Refuse a ``--base-url`` that is not an absolute http(s) or file URL."""
    parts = urlsplit(url)
    if parts.scheme not in URL_SCHEMES or (parts.scheme != "file" and not parts.netloc):
        raise UsageError(
            f"--base-url: expected an http://, https:// or file:// URL, got {url[:80]!r}"
        )


def _print_choice(subjects: list[int], activities: list[str] | None) -> None:
    """One line per chosen subject: person, split, trials and labels from the index."""
    from humotion_gym.mocap.cmu import cmu_index, cmu_label, cmu_person, cmu_subject_id
    from humotion_gym.mocap.library import TEST_SUBJECTS

    print(f"{'subject':8s} {'person':14s} {'split':5s} {'trials':>6s}  labels")
    for s in subjects:
        trials = cmu_index().subject_trials(s)
        labels = Counter(cmu_label(s, t.trial) for t in trials)
        shown = ", ".join(f"{k} {v}" for k, v in labels.most_common())
        split = "test" if cmu_subject_id(s) in TEST_SUBJECTS else "train"
        print(f"{s:<8d} {cmu_person(s):14s} {split:5s} {len(trials):6d}  {shown}")
    if activities:
        print(f"{len(subjects)} subjects chosen for {', '.join(activities)}")
