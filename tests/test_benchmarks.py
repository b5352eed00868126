"""The benchmark scripts: their flags, labels and resumed files (no timing is asserted)."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path
from types import ModuleType

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
