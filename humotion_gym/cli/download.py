"""``humotion-gym download``: fetch public motion capture into the download cache.

::

    humotion-gym download cmu --subjects 2 7 35 [--dest DIR]
    humotion-gym download cmu --verify [--dest DIR]
"""

from __future__ import annotations

import argparse
from pathlib import Path

from humotion_gym.cli._common import UsageError, nonnegative_int, positive_float, positive_int


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``download cmu``."""
    dl = subparsers.add_parser("download", help="fetch public motion capture into the cache")
    dsub = dl.add_subparsers(dest="source", required=True, metavar="SOURCE")
    cmu = dsub.add_parser("cmu", help="CMU Graphics Lab Motion Capture Database (ASF/AMC)")
    cmu.add_argument(
        "--subjects", type=nonnegative_int, nargs="+", default=None, metavar="N",
        help="CMU subject numbers (required unless --verify)",
    )  # fmt: skip
    cmu.add_argument(
        "--dest", type=Path, default=None,
        help="folder to download into (default: the download cache, see humotion-gym cache info)",
    )  # fmt: skip
    cmu.add_argument(
        "--base-url", default=None, help="mirror of the CMU site (default: the CMU site)"
    )
    cmu.add_argument("--quiet", action="store_true", help="no progress bar")
    cmu.add_argument(
        "--retries", type=positive_int, default=3, help="attempts per file (default: 3)"
    )
    cmu.add_argument(
        "--timeout", type=positive_float, default=30.0,
        help="socket timeout per connect and per read, s (default: 30)",
    )  # fmt: skip
    cmu.add_argument(
        "--file-deadline", type=positive_float, default=600.0,
        help="deadline per file or listing, all attempts, s (default: 600)",
    )  # fmt: skip
    cmu.add_argument(
        "--deadline", type=positive_float, default=7200.0,
        help="deadline for the whole run, s (default: 7200)",
    )  # fmt: skip
    cmu.add_argument(
        "--max-asf-mib", type=positive_float, default=1.0,
        help="cap on an .asf file, MiB (default: 1)",
    )  # fmt: skip
    cmu.add_argument(
        "--max-amc-mib", type=positive_float, default=64.0,
        help="cap on an .amc file, MiB (default: 64)",
    )  # fmt: skip
    cmu.add_argument(
        "--max-listing-kib", type=positive_float, default=1024.0,
        help="cap on a subject's HTML listing, KiB (default: 1024)",
    )  # fmt: skip
    cmu.add_argument(
        "--registry", type=Path, default=None,
        help="SHA-256 registry file (default: the packaged cmu_sha256.txt)",
    )  # fmt: skip
    cmu.add_argument(
        "--verify", action="store_true",
        help="download nothing; check DEST: verified / unverified / corrupt (exit 1)",
    )  # fmt: skip
    cmu.set_defaults(func=_cmd_download_cmu)


def _cmd_download_cmu(args: argparse.Namespace) -> int:
    from humotion_gym.mocap import download

    if args.verify:
        report = download.verify_cache(args.dest, registry=args.registry)
        print(report.summary())
        return 0 if report.ok else 1
    if not args.subjects:
        raise UsageError("--subjects is required (or --verify)")
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
