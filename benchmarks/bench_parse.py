"""Parse speed of the BVH and ASF/AMC readers, in MB/s, against np.loadtxt.

Run ``python benchmarks/bench_parse.py``. It times:

- a synthetic 4 MB BVH and a synthetic 4 MB AMC, generated on the fly in a
  temporary folder (so it runs without the shared data);
- the largest BVH and the largest AMC in ``../shared/mocap`` (or
  ``$HUMOTION_SHARED_MOCAP``), when that folder is there.

For each it reports the whole parse (``load_bvh`` / ``load_amc``: header,
checks, numbers) in MB/s of the file, forward kinematics separately, and, as a
same-run reference, ``np.loadtxt`` reading the same numbers: for BVH the motion
block itself; for AMC (whose lines start with bone names and differ in length,
which loadtxt cannot read) the same numbers as one table row per frame.
"""

from __future__ import annotations

import argparse
import io
import os
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
from _timing import best_of

from humotion_gym.cli._common import int_at_least
from humotion_gym.mocap.asfamc import load_amc, load_asf
from humotion_gym.mocap.bvh import load_bvh, write_bvh

ROOT = Path(__file__).resolve().parents[1]


def synthetic_bvh(folder: Path, megabytes: float = 4.0) -> Path:
    rng = np.random.default_rng(0)
    n_j = 31
    channels = [("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")]
    channels += [("Zrotation", "Xrotation", "Yrotation")] * (n_j - 1)
    n_c = sum(len(c) for c in channels)
    n_t = int(megabytes * 1e6 / (n_c * 11.0)) + 1  # about 11 bytes a value at 6 decimals
    path = folder / "synthetic.bvh"
    write_bvh(
        path,
        [f"joint{i}" for i in range(n_j)],
        np.arange(n_j) - 1,
        rng.normal(0, 10, (n_j, 3)),
        channels,
        rng.uniform(-180, 180, (n_t, n_c)),
        1 / 120,
        end_sites={n_j - 1: [0.0, 5.0, 0.0]},
        decimals=6,
    )
    return path


def synthetic_asf_amc(folder: Path, megabytes: float = 4.0) -> tuple[Path, Path]:
    rng = np.random.default_rng(1)
    n_b = 30
    bones = []
    for b in range(n_b):
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        bones.append(
            f"  begin\n    id {b + 1}\n    name bone{b}\n    direction {d[0]} {d[1]} {d[2]}\n"
            f"    length {rng.uniform(1, 8)}\n    axis 0 0 {rng.uniform(-30, 30)} XYZ\n"
            "    dof rx ry rz\n  end\n"
        )
    hierarchy = "\n".join(f"    {'root' if b == 0 else f'bone{b - 1}'} bone{b}" for b in range(n_b))
    asf = folder / "synthetic.asf"
    asf.write_text(
        ":units\n  mass 1.0\n  length 0.45\n  angle deg\n:root\n  order TX TY TZ RX RY RZ\n"
        "  axis XYZ\n  position 0 0 0\n  orientation 0 0 0\n:bonedata\n"
        + "".join(bones)
        + f":hierarchy\n  begin\n{hierarchy}\n  end\n"
    )
    per_frame = 6 * 11 + n_b * (3 * 11 + 7)
    n_t = int(megabytes * 1e6 / per_frame) + 1
    values = rng.uniform(-180, 180, (n_t, 6 + 3 * n_b))
    out = io.StringIO()
    out.write(":FULLY-SPECIFIED\n:DEGREES\n")
    for t in range(n_t):
        row = [f"{v:.6f}" for v in values[t]]
        out.write(f"{t + 1}\nroot {' '.join(row[:6])}\n")
        for b in range(n_b):
            out.write(f"bone{b} {' '.join(row[6 + 3 * b : 9 + 3 * b])}\n")
    amc = folder / "synthetic.amc"
    amc.write_text(out.getvalue())
    return asf, amc


def bvh_numeric_block(path: Path) -> str:
    text = path.read_text()
    i = text.index("Frame Time")
    return text[text.index("\n", i) + 1 :]


def amc_numeric_table(path: Path) -> str:
    """The AMC's numbers, one frame per line, as loadtxt can read them."""
    rows: list[str] = []
    row: list[str] = []
    for line in path.read_text().splitlines():
        toks = line.split()
        if not toks or toks[0].startswith((":", "#")):
            continue
        if len(toks) == 1 and toks[0].isdigit():
            if row:
                rows.append(" ".join(row))
            row = []
        else:
            row.extend(toks[1:])
    rows.append(" ".join(row))
    return "\n".join(rows) + "\n"


def measure(name: str, path: Path, parse: Callable[[], object], block: str, repeat: int) -> dict:
    mb = path.stat().st_size / 1e6
    t_parse = best_of(parse, repeats=repeat, warmup=False)
    clip = parse()
    t_fk = best_of(
        lambda: (clip._positions.clear(), clip.point_positions()),  # type: ignore[attr-defined]
        repeats=repeat,
        warmup=False,
    )
    t_loadtxt = best_of(
        lambda: np.loadtxt(io.StringIO(block)), repeats=max(1, repeat // 2), warmup=False
    )
    return {
        "name": name,
        "mb": mb,
        "frames": clip.n_frames,
        "parse_ms": 1e3 * t_parse,
        "mb_s": mb / t_parse,
        "fk_ms": 1e3 * t_fk,
        "loadtxt_ms": 1e3 * t_loadtxt,
        "ratio": t_loadtxt / t_parse,
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--repeat", type=int_at_least(1), default=5, help="timed runs per file (best kept)"
    )
    parser.add_argument("--megabytes", type=float, default=4.0, help="size of the synthetic files")
    default_shared = os.environ.get("HUMOTION_SHARED_MOCAP") or ROOT.parent / "shared" / "mocap"
    parser.add_argument("--shared", type=Path, default=Path(default_shared))
    args = parser.parse_args()

    results = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        bvh = synthetic_bvh(folder, args.megabytes)
        results.append(
            measure(
                "synthetic BVH",
                bvh,
                lambda: load_bvh(bvh),
                bvh_numeric_block(bvh),
                args.repeat,
            )
        )
        asf, amc = synthetic_asf_amc(folder, args.megabytes)
        sk = load_asf(asf)
        results.append(
            measure(
                "synthetic AMC",
                amc,
                lambda: load_amc(amc, sk),
                amc_numeric_table(amc),
                args.repeat,
            )
        )
    if args.shared.is_dir():
        big_bvh = max(args.shared.rglob("*.bvh"), key=lambda p: p.stat().st_size)
        results.append(
            measure(
                f"{big_bvh.parent.name}/{big_bvh.name}",
                big_bvh,
                lambda: load_bvh(big_bvh),
                bvh_numeric_block(big_bvh),
                args.repeat,
            )
        )
        big_amc = max(args.shared.rglob("*.amc"), key=lambda p: p.stat().st_size)
        real_sk = load_asf(big_amc.parent / f"{big_amc.parent.name}.asf")
        results.append(
            measure(
                f"{big_amc.parent.name}/{big_amc.name}",
                big_amc,
                lambda: load_amc(big_amc, real_sk),
                amc_numeric_table(big_amc),
                args.repeat,
            )
        )
    else:
        print(f"({args.shared} is absent: only the synthetic files are timed)")

    head = (
        f"{'file':<24} {'MB':>5} {'frames':>7} {'parse ms':>9} {'MB/s':>7} "
        f"{'FK ms':>7} {'loadtxt ms':>11} {'loadtxt/parse':>14}"
    )
    print(head)
    print("-" * len(head))
    for r in results:
        print(
            f"{r['name']:<24} {r['mb']:>5.2f} {r['frames']:>7d} {r['parse_ms']:>9.1f} "
            f"{r['mb_s']:>7.1f} {r['fk_ms']:>7.1f} {r['loadtxt_ms']:>11.1f} {r['ratio']:>13.1f}x"
        )
    print(
        f"(best of {args.repeat}; parse = the whole load without forward kinematics; "
        "loadtxt/parse above 1 means faster than np.loadtxt on the same numbers)"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
