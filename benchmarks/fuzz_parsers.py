"""Fuzz the BVH and ASF/AMC readers: N generated, mutated files, each timed and traced.

Run ``python benchmarks/fuzz_parsers.py`` (10,000 cases; ``--cases``, ``--seed``).
The cases come from the generator of ``tests/mocap/test_fuzz.py`` (small valid
files written on the fly, then byte flips, line deletions and duplications,
extreme numbers, huge counts, truncation, deep nesting, many joints...); case
``k`` is generated from seed ``seed + k`` alone, so any case can be replayed
with ``make_case(seed + k)``.

Each case is parsed (``load_bvh``, or ``load_asf`` then ``load_amc``) and, when
it parses, its forward kinematics run, with ``tracemalloc`` tracing the
allocations (numpy reports its arrays to it) and ``time.perf_counter`` timing
it. Printed: the cases, the clean parses, the clean errors by type (and the most
common reasons), the other exceptions (there must be none), the cases over 5 s
and over 500 MB, and the largest time and peak memory. The exit status is 1
when any case raised another exception or went over a bound.
"""

from __future__ import annotations

import argparse
import collections
import re
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "mocap"))

from test_fuzz import describe, make_case, run_case  # noqa: E402

SLOW_SECONDS = 5.0
BIG_BYTES = 500 * 2**20


def _reason(message: str) -> str:
    """The kind of a MocapFormatError: its reason with names and numbers blanked."""
    reason = message.split(": ", 1)[1] if ": " in message else message
    reason = re.sub(r"'[^']*'|\"[^\"]*\"", "'…'", reason)
    reason = re.sub(r"[-+]?\d[\d.e+-]*", "N", reason)
    return reason[:90]


def main(argv: list[str] | None = None) -> int:
    """Run the campaign and print its summary.

    Args:
        argv: Command-line arguments (``sys.argv[1:]`` when None).

    Returns:
        0 when every case parsed or failed cleanly within the bounds, else 1.
    """
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cases", type=int, default=10_000, help="cases to run (10,000)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the first case (0)")
    parser.add_argument("--progress", type=int, default=1000, help="print every N cases")
    args = parser.parse_args(argv)

    results: collections.Counter[str] = collections.Counter()
    errors: collections.Counter[str] = collections.Counter()
    reasons: collections.Counter[str] = collections.Counter()
    kinds: collections.Counter[str] = collections.Counter()
    others: list[str] = []
    slow: list[str] = []
    big: list[str] = []
    max_t = (0.0, "")
    max_m = (0, "")
    t_start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="fuzz_parsers_") as tmp:
        folder = Path(tmp)
        for k in range(args.cases):
            case = make_case(args.seed + k)
            outcome = run_case(case, folder)
            kinds[case.kind] += 1
            results[outcome.result] += 1
            line = describe(case, outcome)
            if outcome.result == "error":
                errors[outcome.error] += 1
                reasons[_reason(outcome.message)] += 1
            elif outcome.result == "other":
                others.append(line)
            if outcome.seconds > SLOW_SECONDS:
                slow.append(line)
            if outcome.peak_bytes > BIG_BYTES:
                big.append(line)
            if outcome.seconds > max_t[0]:
                max_t = (outcome.seconds, line)
            if outcome.peak_bytes > max_m[0]:
                max_m = (outcome.peak_bytes, line)
            if args.progress and (k + 1) % args.progress == 0:
                print(
                    f"  {k + 1} cases, {time.perf_counter() - t_start:.0f} s, "
                    f"{len(others)} other exceptions",
                    flush=True,
                )
    elapsed = time.perf_counter() - t_start

    print(
        f"cases:               {args.cases} (seeds {args.seed}..{args.seed + args.cases - 1}; ",
        end="",
    )
    print(f"{kinds['bvh']} BVH, {kinds['asfamc']} ASF/AMC) in {elapsed:.0f} s")
    print(f"clean parses:        {results['ok']}")
    print(f"clean errors:        {results['error']}")
    for name, n in errors.most_common():
        print(f"  {name}: {n}")
    print("  most common reasons:")
    for reason, n in reasons.most_common(12):
        print(f"    {n:6d}  {reason}")
    print(f"other exceptions:    {len(others)}")
    for line in others[:20]:
        print(f"  {line}")
    print(f"cases over {SLOW_SECONDS:g} s:     {len(slow)}")
    for line in slow[:10]:
        print(f"  {line}")
    print(f"cases over {BIG_BYTES // 2**20} MB:   {len(big)}")
    for line in big[:10]:
        print(f"  {line}")
    print(f"max time:            {max_t[0]:.3f} s  ({max_t[1][:160]})")
    print(f"max memory:          {max_m[0] / 2**20:.1f} MB  ({max_m[1][:160]})")
    print("(times include tracemalloc's overhead, typically 2-3x on the Python-level parts)")
    return 1 if others or slow or big else 0


if __name__ == "__main__":
    raise SystemExit(main())
