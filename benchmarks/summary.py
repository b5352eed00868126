"""Run every benchmark and print one table: figure, value, reference, ratio.

Run: python benchmarks/summary.py [--quick] [--only bench_env bench_vector ...]
     [--data-dir ../shared/mocap] [--markdown]

Each benchmark runs in its own process (one BLAS thread, as the command line
runs), so one cannot slow or break another; its reference is measured in that
same run, and the ratio is the one the benchmark reports (each says against
what). A benchmark that exposes ``rows()`` (``bench_env``, ``bench_vector``)
hands its rows over as JSON; the others print their own tables, which are
read here line by line (:data:`BENCHMARKS` says how). A benchmark that fails,
or prints something no reader recognises, gets a row saying so instead of
stopping the summary. ``--quick`` shortens the slow ones (fewer PPO steps,
fewer particle counts); ``--markdown`` prints the table for the README.

After the table come the speed targets (``speed_history.TARGETS``), each with
its value in this run and whether it was met (judged on the unrounded number
where the benchmark hands its rows over as JSON: a ratio of 0.9496, printed
``0.95x``, misses ``>= 0.95``); ``--record`` adds them to
docs/speed_runs.csv as the next run (a full run only: not with ``--quick``
or ``--only``).
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import re
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import speed_history

HERE = Path(__file__).resolve().parent

#: One line of the summary: what is measured, its value (with unit), the
#: reference measured in the same run, and the ratio as the benchmark states it.
Row = tuple[str, str, str, str]


@dataclass(frozen=True)
class Benchmark:
    """How to run one benchmark script and read its output.

    Attributes:
        name: The script's module name in ``benchmarks/``.
        read: Turns the script's standard output into rows.
        args: Command-line arguments of a full run.
        quick: Arguments of a ``--quick`` run.
        data_dir: Whether the script takes ``--data-dir``.
        rows_call: For a script with a ``rows()`` function, the Python
            expression (in the script's namespace) whose JSON rows are read
            instead of its printed table.
    """

    name: str
    read: Callable[[str], list[Row]]
    args: tuple[str, ...] = ()
    quick: tuple[str, ...] = ()
    data_dir: bool = False
    rows_call: tuple[str, str] | None = None


def _num(text: str) -> float:
    return float(text.replace(",", ""))


def _json_rows(unit: str) -> Callable[[str], list[Row]]:
    def read(out: str) -> list[Row]:
        line = next(x for x in reversed(out.splitlines()) if x.startswith("ROWS "))
        rows = []
        for figure, value, reference, ratio in json.loads(line[5:]):
            if figure == reference:
                continue  # the reference's own row: it is named in the others
            # (bench_env's reset() rows count episodes started, not steps)
            what = "resets/s" if figure.endswith("reset()") else unit
            # printed rounded, and judged against the targets on the numbers themselves
            printed_value = speed_history.Printed(f"{value:,.0f} {what}", value)
            printed_ratio = speed_history.Printed(f"{ratio:.2f}x", ratio)
            rows.append((figure, printed_value, reference, printed_ratio))
        return rows

    return read


def _read_render(out: str) -> list[Row]:
    ref = re.search(r"^CartPole-v1 (.+?):\s+([\d.]+) us/frame", out, re.M)
    reference = f"CartPole-v1 {ref.group(1)} ({ref.group(2)} us)" if ref else "CartPole-v1"
    return [
        (f"render {m[0]}: {m[1].strip()}", f"{m[2]} us/frame", reference, f"{m[3]}x its rate")
        for m in re.findall(
            r"^(\d+x\d+) (.+?)\s+([\d.]+) us/frame .*= \s*([\d.]+)x CartPole", out, re.M
        )
    ]


def _read_observation(out: str) -> list[Row]:
    pattern = (
        r"N=\s*(\d+)([^:]*): log_likelihood\s+([\d.]+) ms \(kinematics\s+([\d.]+)\), "
        r"numpy reference\s+([\d.]+) ms, ratio\s+([\d.]+)x"
    )
    rows: list[Row] = [
        (f"observation model, {int(n):,} poses (128x128){label} (kinematics {k} ms)",
         f"{t} ms", f"numpy reference ({ref} ms)", f"{ratio}x faster")
        for n, label, t, k, ref, ratio in re.findall(pattern, out)
    ]  # fmt: skip
    prepare = r"^prepare( \(.+?\))? \(once per frame, 128x128\):\s+([\d.]+) ms"
    rows += [
        (f"observation model, prepare one frame{label or ''}", f"{t} ms", "", "")
        for label, t in re.findall(prepare, out, re.M)
    ]
    return rows


def _read_fpca(out: str) -> list[Row]:
    ms = {m[0].strip(): m[1] for m in re.findall(r"^(\S.{40,}?)\s+([\d.]+)\s{3}", out, re.M)}
    rows = []
    svd = "plain SVD of the Fourier coefficients"
    it = re.search(r"^(FPCA iteration.*?)\s+([\d.]+)\s+([\d.]+) x plain SVD", out, re.M)
    if it:
        rows.append((it[1], f"{it[2]} ms", f"{svd} ({ms.get(svd, '?')} ms)", f"{it[3]}x the time"))
    fit = re.search(r"fit with imputation / reference FPCA without missing data: ([\d.]+)", out)
    if fit:
        name = next((k for k in ms if k.startswith("FPCA fit")), "FPCA fit with imputation")
        ref = "reference FPCA without missing data"
        rows.append((name, f"{ms.get(name, '?')} ms", f"{ref} ({ms.get(ref, '?')} ms)",
                     f"{fit[1]}x the time"))  # fmt: skip
    return rows


def _read_views(out: str) -> list[Row]:
    """``bench_views``: each call's ms at 2 and 4 views against the same call at one."""
    found = re.findall(r"^(\S.+?)\s+(\d+)\s+([\d.]+)\s+([\d.]+)$", out, re.M)
    return [
        (f"BodyTrack-v2 128x128 {what.strip()}, {views} views", f"{ms} ms",
         f"{what.strip()}, one view", f"{cost}x the time")
        for what, views, ms, cost in found
        if int(views) > 1
    ]  # fmt: skip


def _read_retarget(out: str) -> list[Row]:
    ref = re.search(r"^forward kinematics \(reference\)\s+([\d,]+)", out, re.M)
    reference = f"forward kinematics ({ref[1]} frames/s)" if ref else "forward kinematics"
    return [
        (m[0].strip(), f"{m[1]} frames/s", reference, f"{m[2]}x the time")
        for m in re.findall(r"^(retarget.+?)\s+([\d,]+)\s+([\d.]+)$", out, re.M)
    ]


def _read_parse(out: str) -> list[Row]:
    pattern = (
        r"^(\S.*?)\s+([\d.]+)\s+(\d+)\s+([\d.]+)\s+([\d.]+)\s+([\d.]+)\s+([\d.]+)\s+([\d.]+)x$"
    )
    return [
        (f"parse {m[0]} ({m[1]} MB)", f"{m[4]} MB/s", f"np.loadtxt of its numbers ({m[6]} ms)",
         f"{m[7]}x its speed")
        for m in re.findall(pattern, out, re.M)
    ]  # fmt: skip


def _read_slds(out: str) -> list[Row]:
    data = json.loads(out[out.index("{") : out.rindex("}") + 1])
    f, t = data["fit"], data["transition"]
    return [
        (
            f"SLDS fit, 18 x 50 frames, K = 4, {f['em_iterations']} EM iterations "
            f"(accuracy {f['accuracy']:.3f})",
            f"{f['fit_seconds_median']:.2f} s",
            f"the reference Kalman loop ({f['reference_seconds']:.3f} s)",
            f"{f['fit_over_reference']:.1f}x the time",
        ),
        (
            f"pf-slds transition, {t['particles']:,} particles",
            f"{t['slds_transition_ms']:.2f} ms",
            f"constant velocity's ({t['constant_velocity_transition_ms']:.2f} ms)",
            f"{t['slds_over_constant_velocity']:.1f}x the time",
        ),
    ]


def _read_tree(out: str) -> list[Row]:
    table = re.findall(
        r"^\s*(\d+)\s+\d+\s+[\d.]+\s+([\d.]+)\s+[\d.]+\s+([\d.]+)\s+([\d.]+)\s+[\d.]+\s+(\d+)\s+(\d+)",
        out,
        re.M,
    )
    rows: list[Row] = []
    if table:
        n, tree, exact, kd, x_exact, x_kd = table[-1]
        figure = f"tree sampling (eq. 7), n = {int(n):,} windows"
        rows.append(
            (figure, f"{tree} us", f"exact scan of eq. 3 ({exact} us)", f"{x_exact}x faster")
        )
        rows.append((figure, f"{tree} us", f"scikit-learn KD-tree ({kd} us)", f"{x_kd}x faster"))
    fit = re.search(r"^fit, whole body, ([\d,]+) frames .*: ([\d.]+) s", out, re.M)
    if fit:
        rows.append((f"tree fit, whole body, {fit[1]} frames", f"{fit[2]} s", "", ""))
    for m in re.findall(r"^transition, ([\d,]+) particles, (.+?): ([\d.]+) ms", out, re.M):
        rows.append((f"tree transition, {m[0]} particles, {m[1]}", f"{m[2]} ms", "", ""))
    return rows


def _read_agents(out: str) -> list[Row]:
    # columns: agent, particles, ms/frame, cpu ms, transition, likelihood, prepare, ref ms,
    # x ref, start ms (the episode's first frame)
    rows: list[Row] = []
    for m in re.findall(
        r"^(\S+)\s+([\d,]+)\s+([\d.]+)\s+([\d.]+)\s+[\d.]+\s+[\d.]+\s+[\d.]+\s+([\d.]+)\s+([\d.]+)"
        r"(?:\s+([\d.]+))?$",
        out, re.M,
    ):  # fmt: skip
        ref = f"a plain numpy scorer of the same frame ({m[4]} ms)"
        rows.append(
            (f"{m[0]}, {m[1]} particles, per frame", f"{m[2]} ms", ref, f"{m[5]}x the time")
        )
        rows.append((f"{m[0]}, {m[1]} particles, CPU time per frame (both threads)",
                     f"{m[3]} ms", ref, f"{float(m[3]) / float(m[4]):.2f}x the time"))  # fmt: skip
        if m[6]:
            ratio = float(m[6]) / float(m[4])
            rows.append((f"{m[0]}, {m[1]} particles, episode start (first frame)", f"{m[6]} ms",
                         ref, f"{ratio:.2f}x the time"))  # fmt: skip
    return rows


def _read_rl(out: str) -> list[Row]:
    rows: list[Row] = []
    trivial = re.search(r"trivial env with identical spaces:\s+([\d,]+) env steps/s", out)
    env = re.search(r"^\s+(\S+):\s+([\d,]+) env steps/s$", out, re.M)
    ratio = re.search(r"ratio: ([\d.]+)", out)
    if trivial and env and ratio:
        rows.append(
            (f"PPO training on {env[1]} (DummyVecEnv, 8 envs)", f"{env[2]} env steps/s",
             f"PPO on a trivial env of the same spaces ({trivial[1]} env steps/s)", f"{ratio[1]}x")
        )  # fmt: skip
    bc = re.search(r"bc on (\S+): ([\d,]+) supervised samples/s", out)
    if bc:
        rows.append((f"bc training on {bc[1]}", f"{bc[2]} samples/s", "", ""))
    pf = re.search(r"pf-tree, 300 particles:\s+([\d.]+) ms/frame", out)
    inf = re.search(r"bc:\s+([\d.]+) ms/frame, ([\d.]+)x faster", out)
    if pf and inf:
        rows.append(("bc inference, per frame", f"{inf[1]} ms",
                     f"pf-tree, 300 particles ({pf[1]} ms)", f"{inf[2]}x faster"))  # fmt: skip
    return rows


def _read_leaderboard(out: str) -> list[Row]:
    rows: list[Row] = []
    t_in = re.search(r"in-process:\s+([\d.]+) s", out)
    ray = re.search(r"ray, (\d+) workers:\s+([\d.]+) s", out)
    speedup = re.search(r"speed-up:\s+([\d.]+)x", out)
    if t_in and ray and speedup:
        rows.append((f"leaderboard grid on Ray, {ray[1]} workers", f"{ray[2]} s",
                     f"in-process ({t_in[1]} s)", f"{speedup[1]}x faster"))  # fmt: skip
    episode = re.search(r"episode in the worker:\s+([\d.]+) ms", out)
    cost = re.search(r"Ray per episode:\s+(-?[\d.]+) ms = (-?[\d.]+)% of an episode", out)
    if episode and cost:
        rows.append(("Ray's cost per BodyTrack-v2 episode (pf-cv, 300 particles)",
                     f"{cost[1]} ms", f"the episode in the worker ({episode[1]} ms)",
                     f"{cost[2]}% of it"))  # fmt: skip
    return rows


def _read_fit(out: str) -> list[Row]:
    refs = dict(re.findall(r"^(\S+)\s+reference\s+\d+\s+\d+\s+([\d.]+)", out, re.M))
    pattern = r"^(\S+)\s+(pf-\S+)\s+\d+\s+(\d+)\s+([\d.]+)\s+([\d.]+)\s+([\d.]+)$"
    rows: list[Row] = []
    for task, agent, frames, seconds, ratio, mb in re.findall(pattern, out, re.M):
        # "pf-slds(2p)": the SLDS fit in 2 processes
        name, procs = re.fullmatch(r"(.+?)(?:\((\d+)p\))?", agent).groups()  # type: ignore[union-attr]
        how = "" if procs is None else f", {procs} process{'es' if procs != '1' else ''}"
        rows.append((
            f"{name} prior, first fit on {task}'s training clips ({int(frames):,} frames; "
            f"file {mb} MB{how})", f"{seconds} s",
            f"a numpy Kalman filter pass ({refs.get(task, '?')} s)", f"{ratio}x the time",
        ))  # fmt: skip
    return rows


#: Every benchmark, in the order of the table.
BENCHMARKS: tuple[Benchmark, ...] = (
    Benchmark(
        "bench_env", _json_rows("steps/s"), rows_call=("rows(quick=False)", "rows(quick=True)")
    ),
    Benchmark(
        "bench_vector",
        _json_rows("env steps/s"),
        rows_call=("rows() + ppo_rows()", "rows() + ppo_rows(rounds=6, block=3)"),
    ),
    Benchmark("bench_render", _read_render),
    Benchmark("bench_observation", _read_observation),
    Benchmark(
        "bench_agents",
        _read_agents,
        args=("--repeats", "3"),  # see docs/speed.md: the noise of one pass
        data_dir=True,
        quick=("--particles", "300", "3000", "--frames", "10"),
    ),  # fmt: skip
    Benchmark("bench_tree", _read_tree, data_dir=True),
    Benchmark("bench_fit", _read_fit, data_dir=True, quick=("--tasks", "BodyTrack-v2")),
    Benchmark("bench_slds", _read_slds, args=("--json",), quick=("--json", "--repeats", "1")),
    Benchmark("bench_fpca", _read_fpca),
    Benchmark("bench_views", _read_views),
    Benchmark("bench_parse", _read_parse),
    Benchmark("bench_retarget", _read_retarget),
    Benchmark(
        "bench_rl",
        _read_rl,
        data_dir=True,
        quick=("--rounds", "4", "--episodes", "1"),
    ),  # fmt: skip
    Benchmark(
        "bench_leaderboard",
        _read_leaderboard,
        data_dir=True,
        quick=("--episodes", "10", "--overhead-episodes", "6"),
    ),  # fmt: skip
)


def run(bench: Benchmark, quick: bool, data_dir: str | None, timeout: float) -> list[Row]:
    """Run one benchmark in a fresh process and read its rows."""
    env = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
    if bench.rows_call is not None:
        call = bench.rows_call[1 if quick else 0]
        code = (
            f"import json; from {bench.name} import *; "
            f"print('ROWS ' + json.dumps({call}))"
        )  # fmt: skip
        command = [sys.executable, "-c", code]
    else:
        args = list(bench.quick if quick and bench.quick else bench.args)
        if data_dir and bench.data_dir:
            args += ["--data-dir", data_dir]
        command = [sys.executable, str(HERE / f"{bench.name}.py"), *args]
    try:
        done = subprocess.run(
            command, cwd=HERE, env=env, capture_output=True, text=True, timeout=timeout
        )
    except subprocess.TimeoutExpired:
        return [(bench.name, "", "", f"timed out after {timeout:.0f} s")]
    if done.returncode != 0:
        last = (done.stderr.strip() or done.stdout.strip() or "no output").splitlines()[-1]
        return [(bench.name, "", "", f"failed (exit {done.returncode}): {last}")]
    try:
        rows = bench.read(done.stdout)
    except (ValueError, KeyError, StopIteration, json.JSONDecodeError) as err:
        rows, last = [], f"{type(err).__name__}: {err}"
    else:
        last = "no line recognised"
    return rows or [(bench.name, "", "", f"output not understood ({last[:60]})")]


def format_table(rows: list[tuple[str, Row]], markdown: bool) -> str:
    """The summary as aligned text or as a Markdown table."""
    head = ("benchmark", "figure", "value", "reference (same run)", "ratio")
    lines = [(name, *row) for name, row in rows]
    if markdown:
        out = ["| " + " | ".join(head[1:]) + " | script |", "|---|---|---|---|---|"]
        cells = [[str(c).replace("|", "\\|") for c in line] for line in lines]  # a failure's text
        out += [f"| {f} | {v} | {r} | {x} | `{n}.py` |" for n, f, v, r, x in cells]
        return "\n".join(out)
    widths = [max(len(str(x[i])) for x in [head, *lines]) for i in range(5)]
    fmt = "  ".join(f"{{:{'>' if i in (2, 4) else '<'}{w}}}" for i, w in enumerate(widths))
    return "\n".join(fmt.format(*x) for x in [head, *lines])


def format_targets(
    values: list[tuple[speed_history.Target, str | None]], markdown: bool, quick: bool = False
) -> str:
    """The speed targets' lines: each one's value in this run and whether it was met.

    A ``--quick`` run's are marked: its shorter runs are not the targets' measurements.
    """
    cells = [
        (t.label, "no row" if v is None else v,
         "missing" if v is None else ("met" if speed_history.is_met(t, v) else "not met"))
        for t, v in values
    ]  # fmt: skip
    if markdown:
        run = "this quick run" if quick else "this run"
        out = ["", f"| target | {run} | |", "|---|---|---|"]
        return "\n".join(out + [f"| {a} | {b} | {c} |" for a, b, c in cells])
    width = max(len(a) for a, _, _ in cells)
    title = (
        "targets (a quick run: shorter than the targets' measurements):" if quick else "targets:"
    )
    return "\n".join(["", title] + [f"  {a:{width}}  {b:>6}  {c}" for a, b, c in cells])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="shorter runs of the slow benchmarks")
    ap.add_argument("--only", nargs="+", metavar="NAME", help="run only these (e.g. bench_env)")
    ap.add_argument("--data-dir", default=None, help="real mocap for the benchmarks that take it")
    ap.add_argument("--markdown", action="store_true", help="print a Markdown table")
    ap.add_argument("--timeout", type=float, default=1800.0, help="seconds per benchmark")
    ap.add_argument(
        "--record", type=Path, metavar="CSV",
        help="add the targets to this runs' file (docs/speed_runs.csv) as the next run",
    )  # fmt: skip
    args = ap.parse_args()
    if args.record:  # checked before the minutes of benchmarks, not after
        if args.quick or args.only:
            ap.error("--record takes a full run: not with --quick or --only")
        try:
            speed_history.read_runs(args.record)
            with open(args.record, "a"):
                pass
        except (OSError, ValueError) as err:
            ap.error(f"--record: {err}")
    names = {b.name for b in BENCHMARKS}
    scripts = {path.stem for path in HERE.glob("bench_*.py")}
    unknown = sorted(set(args.only or ()) - names - scripts)
    if unknown:
        ap.error(f"unknown benchmarks {unknown}; they are {sorted(names)}")
    # the benchmarks run in benchmarks/: a relative path is the caller's
    data_dir = str(Path(args.data_dir).resolve()) if args.data_dir else None
    rows: list[tuple[str, Row]] = []
    # A benchmark script without a reader is named, not skipped in silence.
    for path in sorted(HERE.glob("bench_*.py")):
        if path.stem not in names and (not args.only or path.stem in args.only):
            rows.append((path.stem, (path.stem, "", "", "not in the summary: no reader")))
    t0 = time.perf_counter()
    for bench in BENCHMARKS:
        if args.only and bench.name not in args.only:
            continue
        start = time.perf_counter()
        print(f"running {bench.name} ...", file=sys.stderr, flush=True)
        rows += [(bench.name, row) for row in run(bench, args.quick, data_dir, args.timeout)]
        print(f"  {time.perf_counter() - start:.0f} s", file=sys.stderr, flush=True)
    print(format_table(rows, args.markdown))
    print(f"({len(rows)} rows, {time.perf_counter() - t0:.0f} s)", file=sys.stderr)
    try:
        values = speed_history.target_values([row for _, row in rows])
    except ValueError as err:  # a benchmark's rows changed under a target's pattern
        sys.exit(f"summary: {err}; the targets are not read (speed_history.TARGETS)")
    if args.only:  # the targets of the benchmarks run
        values = [(target, value) for target, value in values if value is not None]
    if values:
        print(format_targets(values, args.markdown, args.quick))
    if args.record:
        try:
            number = speed_history.record(args.record, values, datetime.date.today())
        except (OSError, ValueError) as err:
            sys.exit(f"summary: {args.record}: {err}")
        print(f"recorded as run {number} in {args.record}", file=sys.stderr)


if __name__ == "__main__":
    main()
