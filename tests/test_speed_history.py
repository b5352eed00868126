"""benchmarks/speed_history.py: each speed target read over several summary runs."""

from __future__ import annotations

import datetime
import importlib.util
import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
_spec = importlib.util.spec_from_file_location(
    "speed_history", ROOT / "benchmarks/speed_history.py"
)
assert _spec is not None and _spec.loader is not None
speed_history = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(speed_history)

RUNS = """date,run,target,value,met
2026-01-03,3,"fast >= 2",2.5,yes
2026-01-03,3,"slow <= 5",5.4,no
2026-01-02,2,"fast >= 2",1.5,no
2026-01-02,2,"slow <= 5",4.8,yes
2026-01-01,1,"fast >= 2",2.1,yes
2026-01-01,1,"slow <= 5",6.0,no
"""


def _csv(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "runs.csv"
    path.write_text(text)
    return path


def test_each_target_gets_its_median_range_and_met_count(tmp_path: Path) -> None:
    rows = speed_history.read_runs(_csv(tmp_path, RUNS))
    fast, slow = speed_history.history(rows)
    assert fast == ("fast >= 2", 1, 3, 2.1, 1.5, 2.5, 2, 3)
    assert slow == ("slow <= 5", 1, 3, 5.4, 4.8, 6.0, 1, 3)
    (late, _) = speed_history.history(rows, since=2)
    assert (late.first_run, late.median, late.met, late.runs) == (2, 2.0, 1, 2)
    # a target whose timed code changed at run 3 is read from there, the other from 1
    changed = speed_history.Target("slow <= 5", "slow", "value", 5.0, True, since=3)
    fast, slow = speed_history.history(rows, targets=[changed])
    assert (fast.first_run, fast.runs) == (1, 3)
    assert (slow.first_run, slow.last_run, slow.median, slow.runs) == (3, 3, 5.4, 1)


def test_the_repositorys_runs_read(capsys: pytest.CaptureFixture[str]) -> None:
    assert speed_history.main(["--since", "0", "--markdown"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == "| target | runs | median | lowest-highest | met |"
    assert any("pf-tree BodyTrack-v2, 3,000 particles" in line for line in lines)


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ("date,run,target,value\n2026-01-01,1,t,1.0\n", "missing ['met']"),
        ('date,run,target,value,met\n2026-01-01,1,"t",fast,yes\n', "line 2: run must be"),
        ('date,run,target,value,met\n2026-01-01,1,"t",1.0,yes\n2026-01-01,x,"t",1,no\n', "line 3"),
        ('date,run,target,value,met\n2026-01-01,1,"t",1.0,maybe\n', "met must be yes or no"),
    ],
)
def test_a_bad_file_is_one_line_naming_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str, says: str
) -> None:
    path = _csv(tmp_path, text)
    with pytest.raises(ValueError, match=str(path).replace(".", r"\.")) as err:
        speed_history.read_runs(path)
    assert says in str(err.value)
    assert speed_history.main(["--csv", str(path)]) == 1
    err_lines = capsys.readouterr().err.splitlines()
    assert len(err_lines) == 1 and says in err_lines[0]


#: Rows as a summary prints them (run 48), with the rows around each target
#: that a loose pattern would take instead: other sizes, tasks, terms and
#: process counts.
SUMMARY_ROWS = [
    ("BodyTrack-v2 128x128 step", "5,663 steps/s", "CartPole-v1 step + render()", "6.97x"),
    ("BodyTrack-v2 128x128 step + render()", "4,110 steps/s", "CartPole-v1", "5.04x"),
    ("BodyTrack-v2 256x256 step + render()", "3,441 steps/s", "CartPole-v1", "4.08x"),
    ("vector env, 16 x BodyTrack-v2, random actions (episodes end when lost)",
     "7,403 env steps/s", "SyncVectorEnv", "2.14x"),
    ("vector env, 16 x BodyTrack-v2, terminate_on_lost=False (30-frame episodes)",
     "13,403 env steps/s", "SyncVectorEnv", "2.38x"),
    ("PPO on the vector env, 8 x BodyTrack-v2 (18 rotated rounds of one rollout each; "
     "blocks of 6: 0.92-0.95)", "524 env steps/s", "PPO on a trivial env", "0.94x"),
    ("PPO on DummyVecEnv, 8 x BodyTrack-v2 (18 rotated rounds)", "470 env steps/s", "PPO", "0.85x"),
    ("observation model, 3,000 poses (128x128) (kinematics 0.263 ms)", "0.747 ms", "numpy",
     "25.7x faster"),
    ("observation model, 3,000 poses (128x128) (BodyTrack-v2's terms) (kinematics 0.264 ms)",
     "1.043 ms", "numpy", "13.0x faster"),
    ("pf-tree, 3,000 particles, per frame", "5.63 ms", "a plain numpy scorer", "0.41x the time"),
    ("pf-tree, 3,000 particles, episode start (first frame)", "21.57 ms", "scorer", "1.57x"),
    ("pf-tree, 10,000 particles, per frame", "13.66 ms", "a plain numpy scorer", "0.29x the time"),
    ("pf-slds prior, first fit on ArmTrack-v2's training clips (74,422 frames; file 0.15 MB, "
     "2 processes)", "8.40 s", "a numpy Kalman filter pass (0.62 s)", "13.5x the time"),
    ("pf-slds prior, first fit on ArmTrack-v2's training clips (74,422 frames; file 0.15 MB, "
     "1 process)", "11.02 s", "a numpy Kalman filter pass (0.62 s)", "17.7x the time"),
    ("pf-slds prior, first fit on SideWalk-v2's training clips (50,866 frames; file 0.06 MB, "
     "2 processes)", "8.77 s", "a numpy Kalman filter pass (0.47 s)", "18.7x the time"),
]  # fmt: skip
RUN_48 = ["5.04", "0.94", "8.40", "8.77", "13.66", "5.63", "0.747", "2.14"]


def test_each_target_is_read_off_its_own_summary_row() -> None:
    values = speed_history.target_values(SUMMARY_ROWS)
    assert [t.label for t, _ in values] == [t.label for t in speed_history.TARGETS]
    assert [v for _, v in values] == RUN_48
    met = [speed_history.is_met(t, v) for t, v in values if v is not None]
    assert met == [True, False, True, True, True, False, True, True]


def test_a_target_without_its_row_has_no_value_and_two_rows_are_refused() -> None:
    without = [row for row in SUMMARY_ROWS if not row[0].startswith("pf-tree, 3,000")]
    values = dict((t.label, v) for t, v in speed_history.target_values(without))
    assert values["pf-tree BodyTrack-v2, 3,000 particles, ms per frame <= 5"] is None
    failed = [*without, ("bench_agents", "", "", "failed (exit 1): boom")]
    assert dict(speed_history.target_values(failed)) == dict(speed_history.target_values(without))
    with pytest.raises(ValueError, match="2 summary rows match"):
        speed_history.target_values([*SUMMARY_ROWS, SUMMARY_ROWS[1]])


@pytest.mark.parametrize(("value", "met"), [("5", True), ("4.99", True), ("5.01", False)])
def test_a_value_on_the_line_meets_it_either_way(value: str, met: bool) -> None:
    at_most = speed_history.Target("t <= 5", "t", "value", 5.0, True)
    at_least = speed_history.Target("t >= 5", "t", "ratio", 5.0, False)
    assert speed_history.is_met(at_most, value) is met
    assert speed_history.is_met(at_least, value) is (value == "5" or not met)


def test_a_recorded_run_is_the_next_one_newest_first(tmp_path: Path) -> None:
    path = _csv(tmp_path, RUNS)
    values = speed_history.target_values(SUMMARY_ROWS)
    assert speed_history.record(path, values, datetime.date(2026, 1, 4)) == 4
    runs = speed_history.read_runs(path)
    assert [r.run for r in runs[:8]] == [4] * 8 and [r.run for r in runs[8:]] == [3, 3, 2, 2, 1, 1]
    assert [r.value for r in runs[:8]] == [float(v) for v in RUN_48]
    assert [r.met for r in runs[:8]] == [True, False, True, True, True, False, True, True]
    assert path.read_text().splitlines()[1] == (
        '2026-01-04,4,"BodyTrack-v2 step() + render(), x CartPole-v1\'s >= 5",5.04,yes'
    )


def test_the_first_run_follows_a_header_without_its_newline(tmp_path: Path) -> None:
    path = _csv(tmp_path, "date,run,target,value,met")
    values = speed_history.target_values(SUMMARY_ROWS)
    assert speed_history.record(path, values, datetime.date(2026, 1, 4)) == 1
    runs = speed_history.read_runs(path)
    assert [r.run for r in runs] == [1] * 8
    assert [r.value for r in runs] == [float(v) for v in RUN_48]


def test_a_run_with_a_target_missing_is_not_recorded(tmp_path: Path) -> None:
    path = _csv(tmp_path, RUNS)
    values = speed_history.target_values(SUMMARY_ROWS[:3])
    with pytest.raises(ValueError, match="no value for .*PPO on the vector env"):
        speed_history.record(path, values, datetime.date(2026, 1, 4))
    assert path.read_text() == RUNS


def test_the_targets_are_the_runs_files() -> None:
    runs = speed_history.read_runs(speed_history.RUNS_CSV)
    latest = [r.target for r in runs if r.run == runs[0].run]
    assert latest == [t.label for t in speed_history.TARGETS]


@pytest.mark.parametrize(
    ("extra", "says"),
    [
        (["--quick"], "--record takes a full run"),
        (["--only", "bench_env"], "--record takes a full run"),
        ([], "missing ['met']"),
    ],
)
def test_summary_refuses_a_run_it_cannot_record_before_running_it(
    tmp_path: Path, extra: list[str], says: str
) -> None:
    path = _csv(tmp_path, "date,run,target,value\n")
    done = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks/summary.py"), "--record", str(path), *extra],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert done.returncode == 2 and says in done.stderr
    assert "running" not in done.stderr and "Traceback" not in done.stderr


def _summary_module():  # benchmarks/summary.py imports speed_history by its bare name
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        spec = importlib.util.spec_from_file_location("summary", ROOT / "benchmarks/summary.py")
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        sys.modules["summary"] = module  # its dataclasses look their module up
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    return module


def test_a_failed_benchmark_keeps_its_whole_last_line_and_the_table_its_columns() -> None:
    summary = _summary_module()
    message = "a | b " + "x" * 120
    call = f"(_ for _ in ()).throw(SystemExit({message!r}))"
    bench = summary.Benchmark("speed_history", lambda out: [], rows_call=(call, call))
    rows = summary.run(bench, quick=False, data_dir=None, timeout=120)
    assert rows == [("speed_history", "", "", f"failed (exit 1): {message}")]
    table = summary.format_table([(bench.name, rows[0])], markdown=True).splitlines()
    assert table[-1].count(" | ") == table[0].count(" | ")  # the message's | is escaped
    assert "a \\| b" in table[-1]


def test_the_readme_and_the_speed_page_show_the_newest_runs() -> None:
    """README's speed paragraph and speed.md's table are speed_history's, up to the newest run."""
    rows = speed_history.read_runs(speed_history.RUNS_CSV)
    readme = " ".join((ROOT / "README.md").read_text().split())
    said = re.search(
        r"Over runs (\d+)-(\d+), pf-tree at 3,000 particles \((?:runs (\d+)-(\d+), )?median "
        r"([\d.]+) ms a frame, target 5; met in (\d+ of \d+)\) and PPO on the vector env "
        r"\((?:runs (\d+)-(\d+), )?median ([\d.]+)x .*?; met in (\d+ of \d+)\)",
        readme,
    )
    assert said, "README's speed paragraph is not in the form this test reads"
    since, last = int(said[1]), int(said[2])
    assert last == max(r.run for r in rows), "README's speed paragraph misses the newest run"
    table = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks/speed_history.py"), "--since", str(since),
         "--markdown"], capture_output=True, text=True, check=True,
    ).stdout  # fmt: skip
    cells = {line.split(" | ")[0][2:]: line.split(" | ") for line in table.splitlines()[2:]}
    tree = cells["pf-tree BodyTrack-v2, 3,000 particles, ms per frame <= 5"]
    ppo = cells["PPO on the vector env, x PPO on a trivial env >= 0.95"]
    assert (said[5], said[6]) == (tree[2], tree[4].rstrip(" |"))
    assert (said[9], said[10]) == (ppo[2], ppo[4].rstrip(" |"))
    # each target's runs, where the README names them, are the ones the table reads
    assert said[3] is None or f"{said[3]}-{said[4]}" == tree[1]
    assert said[7] is None or f"{said[7]}-{said[8]}" == ppo[1]
    assert table.strip() in (ROOT / "docs/speed.md").read_text(), "speed.md's table is stale"


def test_the_summary_reads_the_agents_wall_and_cpu_times() -> None:
    summary = _summary_module()
    out = (
        "BodyTrack-v2, 30 frames, wall clock, best of 3, OpenCV threads 1\n"
        "agent      particles  ms/frame  cpu ms  transition  likelihood  prepare   ref ms  "
        "x ref start ms\n"
        "pf-tree        3,000      2.49    3.08        1.29        1.37     0.62     8.75   "
        "0.28    12.73\n"
    )
    ref = "a plain numpy scorer of the same frame (8.75 ms)"
    assert summary._read_agents(out) == [
        ("pf-tree, 3,000 particles, per frame", "2.49 ms", ref, "0.28x the time"),
        ("pf-tree, 3,000 particles, CPU time per frame (both threads)", "3.08 ms", ref,
         "0.35x the time"),
        ("pf-tree, 3,000 particles, episode start (first frame)", "12.73 ms", ref,
         "1.45x the time"),
    ]  # fmt: skip
    target = "pf-tree BodyTrack-v2, 3,000 particles, ms per frame <= 5"
    values = dict((t.label, v) for t, v in speed_history.target_values(summary._read_agents(out)))
    assert values[target] == "2.49"


def test_a_target_is_judged_on_the_unrounded_number_the_benchmark_handed_over(
    tmp_path: Path,
) -> None:
    """0.9496 prints 0.95x and misses >= 0.95; 4.996 prints 5.00x and misses >= 5."""
    summary = _summary_module()
    history = summary.speed_history  # the module the summary's cells are made by
    ppo = SUMMARY_ROWS[5][0]
    handed = [
        ["BodyTrack-v2 128x128 step + render()", 4110.2, "CartPole-v1", 4.996],
        [ppo, 519.4, "PPO on a trivial env", 0.9496],
        [SUMMARY_ROWS[3][0], 7403.0, "SyncVectorEnv", 2.004],
    ]
    rows = summary._json_rows("steps/s")("ROWS " + json.dumps(handed))
    assert [(r[1], r[3]) for r in rows] == [
        ("4,110 steps/s", "5.00x"), ("519 steps/s", "0.95x"), ("7,403 steps/s", "2.00x")
    ]  # fmt: skip
    values = dict((t.label, v) for t, v in history.target_values(rows))
    step, vector, fleet = (history.TARGETS[k] for k in (0, 1, 7))
    printed = (values[step.label], values[vector.label], values[fleet.label])
    assert printed == ("5.00", "0.95", "2.00")
    assert [history.is_met(t, values[t.label]) for t in (step, vector, fleet)] == [
        False, False, True,
    ]  # fmt: skip
    # a number read off a printed table has no other: judged as printed
    assert history.is_met(vector, "0.95") is True
    lines = summary.format_targets(history.target_values(rows), markdown=False).splitlines()
    assert any(vector.label in line and line.endswith("0.95  not met") for line in lines)
    # recorded as printed, with met as judged
    path = _csv(tmp_path, RUNS)
    full = [*[r for r in SUMMARY_ROWS if r[0] not in {row[0] for row in rows}], *rows]
    history.record(path, history.target_values(full), datetime.date(2026, 1, 4))
    assert f'2026-01-04,4,"{vector.label}",0.95,no' in path.read_text().splitlines()


def test_the_two_process_slds_target_reads_only_a_fit_in_two_processes() -> None:
    """A fit that used one process (bench_fit's label) leaves the 2-process targets empty."""
    summary = _summary_module()
    out = (
        "task agent clips frames fit s x ref file MB\n"
        "ArmTrack-v2    reference        12    2880    0.02    1.0           (numpy pass)\n"
        "ArmTrack-v2    pf-slds(1p)      12    2880    2.14   89.8     0.05\n"
        "SideWalk-v2    reference        12    2880    0.02    1.0           (numpy pass)\n"
        "SideWalk-v2    pf-slds(2p)      12    2880    2.14   89.8     0.05\n"
    )
    rows = summary._read_fit(out)
    assert rows[0][0].endswith("(2,880 frames; file 0.05 MB, 1 process)")
    values = dict((t.label, v) for t, v in speed_history.target_values(rows))
    assert values["pf-slds prior fit on ArmTrack-v2, 2 processes, s <= 10"] is None
    assert values["pf-slds prior fit on SideWalk-v2, 2 processes, s <= 10"] == "2.14"
