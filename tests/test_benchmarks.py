"""The benchmark scripts: their flags, labels and resumed files (no timing is asserted)."""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
BENCHMARKS = ROOT / "benchmarks"


def _module(name: str) -> ModuleType:
    """A benchmark script as a module (the scripts import their siblings by bare name)."""
    sys.path.insert(0, str(BENCHMARKS))
    try:
        spec = importlib.util.spec_from_file_location(name, BENCHMARKS / f"{name}.py")
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(BENCHMARKS))
    return module


def _script(name: str, *args: str, timeout: float = 120) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run(
        [sys.executable, str(BENCHMARKS / f"{name}.py"), *args],
        capture_output=True, text=True, timeout=timeout, env=env, cwd=ROOT,
    )  # fmt: skip


def test_the_slds_fit_is_labelled_with_the_processes_it_used() -> None:
    """Below slds.PARALLEL_MIN_FRAMES (the synthetic clips) the default fit is one process."""
    done = _script("bench_fit", "--tasks", "ArmTrack-v2", "--agents", "pf-slds", timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    rows = [line.split()[1] for line in done.stdout.splitlines() if "pf-slds(" in line]
    assert rows == ["pf-slds(1p)"]  # not "(2p)", and not fitted again in one process
    assert "default fit used one process" in done.stdout


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["--agents", "pf-pca"], "--agents: pf-pca tracks WalkTrack-v2, SideWalk-v2 only"),
        (["--task", "ArmTrack-v2", "--agents", "pf-cv", "pf-follow"], "pf-follow tracks"),
    ],
)
def test_bench_agents_refuses_an_agent_the_task_lacks_in_one_line(
    args: list[str], says: str
) -> None:
    done = _script("bench_agents", "--frames", "2", "--particles", "30", *args)
    assert done.returncode == 2 and done.stdout == ""  # before the episode is stepped
    last = done.stderr.splitlines()[-1]
    assert last.startswith("bench_agents.py: error: ") and says in last
    assert "Traceback" not in done.stderr


def test_bench_agents_times_a_detector_agent_against_the_plain_scorer() -> None:
    """The reference's distance map is the task's image likelihood's, whatever the agent's."""
    done = _script(
        "bench_agents", "--frames", "2", "--particles", "30", "--agents", "pf-cv-det", timeout=300
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.splitlines()[-1].startswith("pf-cv-det ")


@pytest.mark.parametrize(
    ("script", "args", "says"),
    [
        ("bench_vector", ["--ppo-rounds", "-2"], "--ppo-rounds: expected an integer >= 0"),
        ("bench_rl", ["--rounds", "0"], "--rounds: expected an integer >= 1"),
    ],
)
def test_a_bad_round_count_is_refused_before_any_timing(
    script: str, args: list[str], says: str
) -> None:
    done = _script(script, *args)
    assert done.returncode == 2 and says in done.stderr
    assert "Traceback" not in done.stderr and done.stdout == ""


@pytest.mark.parametrize(
    ("rounds", "label"),
    [
        (1, "; fewer than a block of 6: no spread"),
        (6, "; one block of 6: 0.50"),
        (18, "; blocks of 6: 0.50-0.50"),
        (20, "; blocks of 6: 0.50-0.50 (the last 2 rounds in no block)"),
    ],
)
def test_the_ppo_spread_labels_the_blocks_measured(rounds: int, label: str) -> None:
    bench_vector = _module("bench_vector")
    assert bench_vector._block_spread(np.ones(rounds), np.full(rounds, 2.0), 6) == label


def test_ppo_rows_refuses_a_bad_round_count_by_name() -> None:
    bench_vector = _module("bench_vector")
    with pytest.raises(ValueError, match="ppo_rows: rounds: expected an integer >= 1, got -2"):
        bench_vector.ppo_rows(rounds=-2)


def test_a_missing_reference_names_the_extra_that_holds_it(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    pytest.importorskip("tomllib", reason="tomllib is Python 3.11's")
    timing = _module("_timing")
    assert [timing.extra_of(m) for m in ("ray", "sklearn", "pygame", "torch")] == [
        "distributed", "bench", "bench", "rl",
    ]  # fmt: skip
    monkeypatch.setattr(timing.importlib.util, "find_spec", lambda name: None)
    with pytest.raises(SystemExit) as done:
        timing.require("ray", "the Ray engine")
    assert str(done.value).endswith(
        "install the distributed extra: pip install -e '.[distributed]'"
    )


def _cell(agent: str, episodes: int, seeds: list[int], variant: str = "a v1") -> dict[str, Any]:
    errors = [float(k) for k in range(episodes)]
    return {
        "task": "BodyTrack-v2", "variant": variant, "agent": agent, "episodes": episodes,
        "seeds": seeds, "subjects": ["cmu-01"], "clip_ids": [f"c{k}" for k in range(episodes)],
        "agent_errors_mm": [errors for _ in seeds], "hold_errors_mm": [e + 1 for e in errors],
        "seconds": 1.0,
    }  # fmt: skip


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["--agent", "hold"], "agent pf-mix (given hold)"),
        (["--episodes", "3"], "episodes 2 (given 3)"),
        (["--seeds", "1"], "seeds [0] (given [1])"),
    ],
)
def test_v2_limbs_refuses_to_resume_a_file_of_other_settings(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], says: str
) -> None:
    v2_limbs = _module("v2_limbs")
    out = tmp_path / "limbs.json"
    out.write_text(json.dumps({"cells": [_cell("pf-mix", 2, [0])]}))
    base = ["--data-dir", str(tmp_path / "none"), "--out", str(out), "--episodes", "2"]
    with pytest.raises(SystemExit) as done:  # before the (missing) library is read
        v2_limbs.main([*base, "--seeds", "0", "--variants", "a v1", "b shaded", *args])
    assert done.value.code == 2
    err = capsys.readouterr().err.splitlines()[-1]
    assert f"--out: {out}: its BodyTrack-v2 'a v1' cell was run with {says}" in err
    # the same settings resume it (the file's cells are kept)
    assert v2_limbs.resumed_cells(out, "pf-mix", 2, [0]) == [_cell("pf-mix", 2, [0])]


def test_v2_limbs_reads_an_older_files_settings_off_its_cells(tmp_path: Path) -> None:
    v2_limbs = _module("v2_limbs")
    old = {k: v for k, v in _cell("pf-mix", 2, [0, 1]).items() if k not in ("episodes", "seeds")}
    out = tmp_path / "limbs.json"
    out.write_text(json.dumps({"cells": [old]}))
    assert v2_limbs.resumed_cells(out, "pf-mix", 2, [0, 1]) == [old]
    with pytest.raises(ValueError, match=r"2 seeds \(given \[0\]\)"):
        v2_limbs.resumed_cells(out, "pf-mix", 2, [0])


def test_v2_limbs_table_names_the_agent_that_ran() -> None:
    v2_limbs = _module("v2_limbs")
    cells = [_cell("hold", 2, [0]), _cell("hold", 2, [0], variant="b shaded")]
    table = v2_limbs.markdown(v2_limbs.summarize(cells))
    assert table.splitlines()[0].startswith("| task | variant | hold mm [95% CI] | hold mm |")
    pf = v2_limbs.markdown(v2_limbs.summarize([_cell("pf-mix", 2, [0])]))
    assert "| pf-mix mm [95% CI] |" in pf.splitlines()[0]
