"""Fuzzing the BVH and ASF/AMC readers: every input parses cleanly or fails cleanly, cheaply.

Each case is generated from its seed alone: a small valid BVH file, or a valid
ASF skeleton and an AMC motion on it, written here (never copied from the shared
data), then mutated one to three times: byte flips, bit flips, line deletions,
duplications (up to a thousand copies) and swaps, truncation, inserted garbage
(NUL, lone carriage returns, superscripts, other scripts' digits), numbers
replaced by extremes (``1e308``, ``-0``, ``nan``, ``inf``, ``1e-310``,
``2**63``, ``²``, thirty nines...), counts and frame times replaced
(``Frames: 10**12``, ``Frame Time: 33.3333``, AMC frame numbers of ``10**7``),
deep nesting and many joints or bones.

The outcome of a case is either a clean parse, after which the forward
kinematics must run and give positions of the right shape, or a
:class:`~humotion_gym.errors.MocapFormatError`. No other exception type is
accepted (numpy ``RuntimeWarning`` s count as failures too); each case's work,
counted in function calls, must stay linear in its size (:data:`MAX_BASE_CALLS`
plus :data:`MAX_CALLS_PER_BYTE` a byte) and it must allocate under
:data:`MAX_PEAK_BYTES` at its peak (``tracemalloc``, which numpy reports its
arrays to).

``benchmarks/fuzz_parsers.py`` runs the same generator for thousands of cases.
"""

from __future__ import annotations

import re
import time
import tracemalloc
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

from humotion_gym.errors import MocapFormatError
from humotion_gym.mocap.asfamc import load_amc, load_asf
from humotion_gym.mocap.bvh import load_bvh

#: The per-case bound on work: function calls (Python and built-in) at most
#: MAX_BASE_CALLS plus MAX_CALLS_PER_BYTE per byte of the case's files, so the
#: work stays linear in the input. Counted on a case's second run (a first
#: use of a code path adds up to 26,000 calls of imports and compiled
#: patterns), the 320 cases need at most 4 calls a byte plus 729 (315,429
#: calls for the largest, 166,328 bytes).
MAX_BASE_CALLS = 20_000
MAX_CALLS_PER_BYTE = 4
#: The per-case bound on the peak of traced allocations, in bytes.
MAX_PEAK_BYTES = 200 * 2**20
#: Cases per test batch and batches: 320 cases in all.
BATCH = 40
N_BATCHES = 8

# Values a number may be replaced with: extremes, non-numbers, look-alikes.
EXTREMES = [
    "1e308",
    "-1e308",
    "1e400",
    "1e-310",
    "-0",
    "0",
    "-1",
    "nan",
    "-nan",
    "inf",
    "-inf",
    str(2**31),
    str(2**63),
    str(2**63 - 1),
    str(2**64),
    "9" * 30,
    "9" * 5000,
    "²",
    "1²",
    "١٢",
    "0x1F",
    "1_000",
    "1e",
    ".",
    "-",
    "33.3333",
    "1000",
    "1000000",
    "10000000",
    "1e-5",
    "0.00001",
]
GARBAGE = [b"\x00", b"\r", b"\xff\xfe", "²".encode(), "١".encode(), b"{", b"}", b"#", b":", b"\t"]
_NUMBER = re.compile(rb"(?<![\w.])[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?(?![\w.])")
_ROT = ("Xrotation", "Yrotation", "Zrotation")
_POS = ("Xposition", "Yposition", "Zposition")


# --------------------------------------------------------------------------
# Valid files.
# --------------------------------------------------------------------------


def _num(rng: np.random.Generator, lo: float, hi: float) -> str:
    """A number in [lo, hi) written with 0 to 6 decimals, or as a repr."""
    v = float(rng.uniform(lo, hi))
    digits = int(rng.integers(0, 8))
    return repr(v) if digits == 7 else f"{v:.{digits}f}"


def _tree(rng: np.random.Generator, n: int) -> list[int]:
    """Parents of ``n`` nodes, -1 for the first, each other below an earlier one."""
    return [-1] + [int(rng.integers(0, j)) for j in range(1, n)]


def valid_bvh(rng: np.random.Generator) -> str:
    """A small valid BVH: 1-6 joints, random channels, end sites, 0-5 frames."""
    n = int(rng.integers(1, 7))
    parents = _tree(rng, n)
    children: list[list[int]] = [[] for _ in range(n)]
    for j, p in enumerate(parents[1:], 1):
        children[p].append(j)
    chans: list[tuple[str, ...]] = []
    for j in range(n):
        rot = tuple(rng.permutation(_ROT))
        kind = int(rng.integers(0, 4)) if j else 3
        chans.append([(), rot, (*_POS, *rot), ("Zrotation",)][kind] if j else (*_POS, *rot))
    ind = rng.choice(["  ", "\t", " "])
    nl = "\r\n" if rng.random() < 0.2 else "\n"
    out = ["HIERARCHY"]

    def emit(j: int, depth: int) -> None:
        pad = ind * depth
        out.append(f"{pad}{'JOINT' if parents[j] >= 0 else 'ROOT'} j{j}")
        out.append(f"{pad}{{")
        out.append(f"{pad}{ind}OFFSET {' '.join(_num(rng, -20, 20) for _ in range(3))}")
        out.append(f"{pad}{ind}CHANNELS {len(chans[j])} {' '.join(chans[j])}".rstrip())
        if not children[j]:
            out.extend([f"{pad}{ind}End Site", f"{pad}{ind}{{"])
            out.append(f"{pad}{ind * 2}OFFSET {' '.join(_num(rng, -5, 5) for _ in range(3))}")
            out.append(f"{pad}{ind}}}")
        for c in children[j]:
            emit(c, depth + 1)
        out.append(f"{pad}}}")

    emit(0, 0)
    frames = int(rng.integers(0, 6))
    width = sum(map(len, chans))
    out += ["MOTION", f"Frames: {frames}"]
    out.append(f"Frame Time: {rng.choice(['0.0083333', '0.033333', '0.01', '0.5', '1'])}")
    out += [" ".join(_num(rng, -180, 180) for _ in range(width)) for _ in range(frames)]
    return nl.join(out) + nl


def valid_asf_amc(rng: np.random.Generator) -> tuple[str, str]:
    """A small valid ASF (1-6 bones) and an AMC of 1-5 frames on it."""
    n = int(rng.integers(1, 7))
    parents = [p - 1 for p in _tree(rng, n + 1)[1:]]  # -1: the root
    root_rot = " ".join(rng.permutation(["RX", "RY", "RZ"]))
    asf = [
        "# generated",
        ":version 1.10",
        ":name fuzz",
        ":units",
        "  mass 1.0",
        f"  length {rng.choice(['0.45', '1', '25.4'])}",
        "  angle deg",
        ":documentation",
        "  fuzz",
        ":root",
        f"   order TX TY TZ {root_rot}",
        f"   axis {''.join(rng.permutation(list('XYZ')))}",
        f"   position {' '.join(_num(rng, -5, 5) for _ in range(3))}",
        f"   orientation {' '.join(_num(rng, -90, 90) for _ in range(3))}",
        ":bonedata",
    ]
    dofs: list[list[str]] = []
    for b in range(n):
        dof = [str(d) for d in rng.permutation(["rx", "ry", "rz"])[: int(rng.integers(0, 4))]]
        dofs.append(dof)
        asf += [
            "  begin",
            f"     id {b + 1}",
            f"     name b{b}",
            f"     direction {' '.join(_num(rng, -1, 1) for _ in range(2))} 1",
            f"     length {_num(rng, 0.5, 10)}",
            f"     axis {' '.join(_num(rng, -90, 90) for _ in range(3))} "
            f"{''.join(rng.permutation(list('XYZ')))}",
        ]
        if dof:
            asf.append(f"    dof {' '.join(dof)}")
            asf.append("    limits " + "\n           ".join("(-180.0 180.0)" for _ in dof))
        asf.append("  end")
    asf += [":hierarchy", "  begin"]
    for p in range(-1, n):
        kids = [f"b{b}" for b in range(n) if parents[b] == p]
        if kids:
            asf.append(f"    {'root' if p < 0 else f'b{p}'} {' '.join(kids)}")
    asf.append("  end")

    start = int(rng.choice([0, 1, 1, 1, 17]))
    amc = ["#!OML:ASF fuzz.asf", ":FULLY-SPECIFIED", ":DEGREES"]
    for f in range(int(rng.integers(1, 6))):
        amc.append(str(start + f))
        lines = [f"root {' '.join(_num(rng, -180, 180) for _ in range(6))}"]
        lines += [
            f"b{b} {' '.join(_num(rng, -180, 180) for _ in dof)}"
            for b, dof in enumerate(dofs)
            if dof
        ]
        if rng.random() < 0.2:
            lines = [str(x) for x in rng.permutation(lines)]
        amc += lines
    return "\n".join(asf) + "\n", "\n".join(amc) + "\n"


# --------------------------------------------------------------------------
# Mutations.
# --------------------------------------------------------------------------


def _lines(data: bytes) -> list[bytes]:
    return data.split(b"\n")


def _pick_line(rng: np.random.Generator, lines: list[bytes]) -> int:
    return int(rng.integers(0, len(lines)))


def _deep_bvh(rng: np.random.Generator, data: bytes) -> bytes:
    """A chain of many nested joints inserted below the first OFFSET (braces maybe unclosed)."""
    n = int(rng.choice([50, 300, 2000]))
    chain = b"".join(b"JOINT d%d\n{\nOFFSET 0 0 1\nCHANNELS 0\n" % i for i in range(n))
    close = b"}\n" * n if rng.random() < 0.7 else b""
    i = data.find(b"OFFSET")
    i = data.find(b"\n", i) + 1 if i >= 0 else 0
    return data[:i] + chain + b"End Site\n{\nOFFSET 0 0 1\n}\n" + close + data[i:]


def _many_bvh(rng: np.random.Generator, data: bytes) -> bytes:
    """Many sibling joints (some with clashing names) inserted below the first OFFSET."""
    n = int(rng.choice([100, 1200, 3000]))
    body = b"".join(b"JOINT m%d\n{\nOFFSET 1 0 0\nCHANNELS 0\n}\n" % i for i in range(n))
    if rng.random() < 0.3:
        body += b"JOINT m0_End\n{\nOFFSET 1 0 0\n}\n"
    i = data.find(b"OFFSET")
    i = data.find(b"\n", i) + 1 if i >= 0 else 0
    return data[:i] + body + data[i:]


def _many_bones(rng: np.random.Generator, data: bytes, deep: bool) -> bytes:
    """Many bones (a chain when ``deep``, else siblings) added to an ASF."""
    n = int(rng.choice([50, 300, 1500]))
    bones = b"".join(
        b"begin\nname x%d\ndirection 0 1 0\nlength 1\naxis 0 0 0 XYZ\ndof rx\nend\n" % i
        for i in range(n)
    )
    if deep:
        links = b"root x0\n" + b"".join(b"x%d x%d\n" % (i, i + 1) for i in range(n - 1))
    else:
        links = b"root " + b" ".join(b"x%d" % i for i in range(n)) + b"\n"
    data = data.replace(b":bonedata\n", b":bonedata\n" + bones, 1)
    return data.replace(b":hierarchy\n  begin\n", b":hierarchy\n  begin\n" + links, 1)


def mutate(rng: np.random.Generator, data: bytes, kind: str) -> tuple[bytes, str]:
    """One random mutation of a file's bytes.

    Args:
        rng: The case's generator.
        data: The file.
        kind: ``"bvh"``, ``"asf"`` or ``"amc"``: which structural mutations apply.

    Returns:
        The mutated bytes and a short description.
    """
    ops = ["flip", "bit", "delete", "duplicate", "swap", "truncate", "insert"]
    ops += ["number", "number", "benign"]
    ops += {
        "bvh": ["frames", "frame_time", "channels", "deep", "many"],
        "asf": ["deep", "many", "units", "length", "dof"],
        "amc": ["frame_number", "frame_number", "gap"],
    }[kind]
    op = str(rng.choice(ops))
    if not data:
        return b"\n", "empty->newline"
    lines = _lines(data)
    if op == "flip":
        i = int(rng.integers(0, len(data)))
        return data[:i] + bytes([int(rng.integers(0, 256))]) + data[i + 1 :], f"flip@{i}"
    if op == "bit":
        i = int(rng.integers(0, len(data)))
        return data[:i] + bytes([data[i] ^ (1 << int(rng.integers(0, 8)))]) + data[i + 1 :], "bit"
    if op == "delete":
        k = _pick_line(rng, lines)
        del lines[k]
        return b"\n".join(lines), f"delete line {k + 1}"
    if op == "duplicate":
        k = _pick_line(rng, lines)
        times = int(rng.choice([1, 2, 1000]))
        lines[k : k + 1] = [lines[k]] * (times + 1)
        return b"\n".join(lines), f"duplicate line {k + 1} x{times}"
    if op == "swap":
        a, b = _pick_line(rng, lines), _pick_line(rng, lines)
        lines[a], lines[b] = lines[b], lines[a]
        return b"\n".join(lines), f"swap lines {a + 1} {b + 1}"
    if op == "truncate":
        i = int(rng.integers(0, len(data)))
        return data[:i], f"truncate@{i}"
    if op == "insert":
        i = int(rng.integers(0, len(data) + 1))
        g = GARBAGE[int(rng.integers(0, len(GARBAGE)))]
        return data[:i] + g + data[i:], f"insert {g!r}@{i}"
    if op == "number":
        spans = [m.span() for m in _NUMBER.finditer(data)]
        if not spans:
            return data, "number (none)"
        a, b = spans[int(rng.integers(0, len(spans)))]
        new = EXTREMES[int(rng.integers(0, len(EXTREMES)))]
        return data[:a] + new.encode() + data[b:], f"number {data[a:b]!r}->{new[:20]}"
    if op == "benign":  # a plausible number for another: the file often stays valid
        spans = [m.span() for m in _NUMBER.finditer(data)]
        if not spans:
            return data, "benign (none)"
        a, b = spans[int(rng.integers(0, len(spans)))]
        new = str(rng.choice(["0", "-0", "1", "0.5", "-2.25", "1e-3", "12", "3"]))
        return data[:a] + new.encode() + data[b:], f"benign {data[a:b]!r}->{new}"
    if op == "frames":
        new = str(rng.choice(["1000000000000", "1000001", "1", "0", "²", "-1", "9" * 40]))
        return re.sub(rb"Frames:[^\n]*", b"Frames: " + new.encode(), data), f"Frames: {new}"
    if op == "frame_time":
        new = str(rng.choice(["1000", "33.3333", "1e-310", "1e308", "0", "-0.01", "nan", "1e-5"]))
        return re.sub(rb"Frame Time:[^\n]*", b"Frame Time: " + new.encode(), data), f"ft {new}"
    if op == "channels":
        new = str(rng.choice(["²", "7", "65", "0", "99999999999999999999"]))
        return re.sub(rb"CHANNELS \d+", b"CHANNELS " + new.encode(), data, count=1), f"CH {new}"
    if op == "deep":
        if kind == "bvh":
            return _deep_bvh(rng, data), "deep nesting"
        return _many_bones(rng, data, deep=True), "deep bones"
    if op == "many":
        if kind == "bvh":
            return _many_bvh(rng, data), "many joints"
        return _many_bones(rng, data, deep=False), "many bones"
    if op == "units":
        new = str(rng.choice(["1e308", "1e-308", "0", "-1", "nan", "1e-4"]))
        return re.sub(rb"length [^\n]*", b"length " + new.encode(), data, count=1), f"unit {new}"
    if op == "length":
        new = str(rng.choice(["1e308", "0", "-1", "-0", "inf", "200000"]))
        return re.sub(
            rb"\n( *)length [^\n]*\n( *)axis",
            rb"\n\1length " + new.encode() + rb"\n\2axis",
            data,
            count=1,
        ), f"len {new}"
    if op == "dof":
        new = str(rng.choice(["rx rx", "rx ry rz rx", "tx", "RX Ry", "l"]))
        return re.sub(rb"dof [^\n]*", b"dof " + new.encode(), data, count=1), f"dof {new}"
    # AMC frame numbers.
    frame_lines = [k for k, ln in enumerate(lines) if ln.strip().isdigit()]
    if not frame_lines:
        return data, f"{op} (none)"
    k = frame_lines[int(rng.integers(0, len(frame_lines)))]
    if op == "gap":
        new = str(int(lines[k]) + int(rng.choice([999, 1000, 1001, 5000, 10**6])))
    else:
        new = str(rng.choice(["1000000", "10000000", str(2**63), str(2**62), "0", "9" * 40]))
    lines[k] = new.encode()
    return b"\n".join(lines), f"frame number line {k + 1} -> {new[:20]}"


# --------------------------------------------------------------------------
# Cases.
# --------------------------------------------------------------------------


@dataclass
class Case:
    """One fuzz case: the files to write and what was done to them.

    Attributes:
        seed: The seed the case was generated from.
        kind: ``"bvh"`` or ``"asfamc"``.
        files: File name to bytes: ``clip.bvh``, or ``skel.asf`` and ``clip.amc``.
        mutations: What was done, in order.
    """

    seed: int
    kind: str
    files: dict[str, bytes]
    mutations: list[str] = field(default_factory=list)


@dataclass
class Outcome:
    """What parsing one case gave.

    Attributes:
        result: ``"ok"`` (a clean parse, kinematics run), ``"error"`` (a
            MocapFormatError) or ``"other"`` (any other exception).
        error: The exception's type name, or ``""``.
        message: The exception's message, or ``""``.
        seconds: Wall time of the parse and kinematics (for the benchmark).
        peak_bytes: Peak of traced allocations during them.
        calls: Function calls made during them (0 unless counted).
        size: Bytes of the case's files.
    """

    result: str
    error: str
    message: str
    seconds: float
    peak_bytes: int
    calls: int = 0
    size: int = 0


def make_case(seed: int, mutations: int | None = None) -> Case:
    """Generate the case of a seed: valid files, then 1-3 mutations (or ``mutations``).

    One mutation half the time, two a third of the time, three a sixth.

    Args:
        seed: The seed; the case depends on it alone.
        mutations: How many mutations (random 1-3 when None; 0 gives the valid files).

    Returns:
        The case.
    """
    rng = np.random.default_rng(seed)
    kind = "bvh" if rng.random() < 0.5 else "asfamc"
    if kind == "bvh":
        files = {"clip.bvh": valid_bvh(rng).encode()}
    else:
        asf, amc = valid_asf_amc(rng)
        files = {"skel.asf": asf.encode(), "clip.amc": amc.encode()}
    case = Case(seed, kind, files)
    count = int(rng.choice([1, 1, 1, 2, 2, 3])) if mutations is None else mutations
    for _ in range(count):
        name = "clip.bvh" if kind == "bvh" else str(rng.choice(["skel.asf", "clip.amc"]))
        files[name], what = mutate(rng, files[name], name.rsplit(".", 1)[1])
        case.mutations.append(f"{name}: {what}")
    return case


def parse_case(case: Case, folder: Path) -> None:
    """Write the case's files to ``folder``, parse them and run the kinematics.

    Raises:
        MocapFormatError: If a file is refused.
        AssertionError: If the positions have the wrong shape.
    """
    paths = {}
    for name, data in case.files.items():
        paths[name] = folder / name
        paths[name].write_bytes(data)
    if case.kind == "bvh":
        clip = load_bvh(paths["clip.bvh"])
    else:
        clip = load_amc(paths["clip.amc"], load_asf(paths["skel.asf"]))
    pos = clip.point_positions()
    assert pos.shape == (clip.n_frames, len(clip.point_names), 3)


def parse_outcome(case: Case, folder: Path) -> tuple[str, str, str]:
    """Parse one case, numpy's ``RuntimeWarning`` s as errors, and say how it went.

    Returns:
        ``(result, error, message)`` as in :class:`Outcome`; exceptions other
        than MocapFormatError are caught and reported as ``"other"``, never raised.
    """
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)
            parse_case(case, folder)
        return "ok", "", ""
    except MocapFormatError as exc:
        return "error", type(exc).__name__, str(exc)
    except Exception as exc:  # noqa: BLE001 - the point is to catch anything else
        return "other", type(exc).__name__, str(exc)[:500]


def run_case(case: Case, folder: Path, count: Callable[..., int] | None = None) -> Outcome:
    """Parse one case, timing it, tracing its allocations and (given ``count``) its calls.

    Args:
        case: The case.
        folder: Where to write its files.
        count: ``count(fn)`` runs ``fn`` and returns the function calls it made
            (the ``count_calls`` fixture); None leaves them uncounted.

    Returns:
        The outcome of the traced run (see :func:`parse_outcome`).
    """
    for name, data in case.files.items():
        (folder / name).write_bytes(data)
    got: list[tuple[str, str, str]] = []

    def attempt() -> None:
        got.append(parse_outcome(case, folder))

    tracemalloc.start()
    t0 = time.perf_counter()
    attempt()
    seconds = time.perf_counter() - t0
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    # Counted on a second run: the first paid the one-off costs (imports,
    # compiled patterns), which no input size explains, and at most a few
    # kilobytes of them count in its peak.
    calls = count(attempt) if count is not None else 0
    size = sum(len(data) for data in case.files.values())
    return Outcome(*got[0], seconds, peak, calls, size)


def describe(case: Case, outcome: Outcome) -> str:
    """One line for a failing case: its seed, mutations and outcome."""
    return (
        f"seed {case.seed} ({case.kind}; {'; '.join(case.mutations)}): {outcome.result} "
        f"{outcome.error} {outcome.message[:200]!r} in {outcome.seconds:.2f} s, "
        f"{outcome.calls:,} calls for {outcome.size:,} bytes, {outcome.peak_bytes / 2**20:.0f} MB"
    )


# --------------------------------------------------------------------------
# Tests.
# --------------------------------------------------------------------------


def test_generated_files_are_valid(tmp_path):
    for seed in range(40):
        parse_case(make_case(seed, mutations=0), tmp_path)


@pytest.mark.parametrize("batch", range(N_BATCHES))
def test_mutated_files_parse_or_fail_cleanly_and_cheaply(tmp_path, batch, count_calls):
    failures = []
    results = []
    for seed in range(batch * BATCH, (batch + 1) * BATCH):
        case = make_case(10_000 + seed)
        outcome = run_case(case, tmp_path, count_calls)
        results.append(outcome.result)
        if (
            outcome.result == "other"
            or outcome.calls > MAX_BASE_CALLS + MAX_CALLS_PER_BYTE * outcome.size
            or outcome.peak_bytes > MAX_PEAK_BYTES
        ):
            failures.append(describe(case, outcome))
    assert not failures, "\n".join(failures)
    # The mutations neither always break the files nor never do.
    assert 0 < results.count("error") < len(results), results


def test_error_messages_name_the_file_and_a_line(tmp_path):
    seen = 0
    for seed in range(60):
        result, _, message = parse_outcome(make_case(20_000 + seed), tmp_path)  # (untraced)
        if result == "error":
            seen += 1
            assert re.match(
                rf"{re.escape(str(tmp_path))}/(clip\.bvh|skel\.asf|clip\.amc), line \d+: \S",
                message,
            ), message
    assert seen > 10


def test_the_runner_reports_other_exceptions_without_raising(tmp_path, monkeypatch):
    import humotion_gym.mocap.bvh as bvh_module

    def broken(*args, **kwargs):
        raise IndexError("boom")

    monkeypatch.setattr(bvh_module, "_read_motion", broken)
    case = next(c for c in map(make_case, range(100)) if c.kind == "bvh")
    case = make_case(case.seed, mutations=0)
    outcome = run_case(case, tmp_path)
    assert (outcome.result, outcome.error) == ("other", "IndexError")


def test_cases_depend_on_the_seed_alone():
    a, b = make_case(123), make_case(123)
    assert a.files == b.files and a.mutations == b.mutations
