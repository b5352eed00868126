"""benchmarks/speed_history.py: each speed target read over several summary runs."""

from __future__ import annotations

import importlib.util
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
