"""The recorded small table (results/ci_small) reproduces; results.json records the platform.

``results/ci_small`` was written by (about 8 s on one core)::

    humotion-gym leaderboard --tasks ArmTrack-v2 SideWalk-v2 --agents hold pf-cv pf-tree \\
        --particles 100 --episodes 8 --seed 0 --out results/ci_small --no-report

on the built-in synthetic motion, then compacted
(:func:`baselines.leaderboard.results.compact`: floats kept to 7 significant
digits). The test reruns the recorded config through the public API and
compares (docs/leaderboard.md, "The recorded CI table"):

* ``hold``: every episode's mean error to the 7 significant digits the record
  keeps (relative 1e-6, at most 0.0005 mm here). Its error is the kinematics
  of the held pose against the true pose, no search: across CPUs it differs by
  about 1e-13 mm.
* The particle filters: each cell's mean error over its 8 episodes within 20%
  relative. On the machine that recorded them they are equal to the digit; on
  another CPU a last-bit difference in a sine or BLAS product makes another
  sample path (resampling turns it into other particles), so per-episode
  errors may differ there. What another sample path does to a cell's mean was
  measured as 10 agent seeds on the same 8 episodes (each seed an independent
  sample path, the most a last-bit difference can change): the cells' mean
  errors spread by 2.2-3.7% (relative standard deviation), the largest
  distance between two seeds' means was 10%, and from the recorded seed's 9.8%.
  20% is twice the largest distance seen and 3.8 standard deviations of the
  difference of two paths on the widest cell (SideWalk-v2 pf-cv).
"""

from __future__ import annotations

import gzip
import importlib.metadata
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from baselines.leaderboard import platform_info, run_leaderboard
from baselines.leaderboard.platform_info import run_platform
from baselines.leaderboard.tables import FLOOR

RECORDED = Path(__file__).resolve().parents[2] / "results" / "ci_small" / "results.json.gz"
#: hold's per-episode agreement: the record's 7 significant digits.
HOLD_RTOL = 1e-6
#: The particle filters' per-cell agreement of the mean error (module docstring).
FILTER_RTOL = 0.20
PLATFORM_KEYS = {"packages", "platform", "machine", "cpu", "cpu_count", "blas", "threads"}
PACKAGE_KEYS = {
    "python", "numpy", "scipy", "numba", "opencv", "gymnasium", "torch", "stable-baselines3",
}  # fmt: skip


def _recorded() -> dict[str, Any]:
    return json.loads(gzip.decompress(RECORDED.read_bytes()))


def _episodes(rows: list[dict[str, Any]]) -> dict[tuple[str, str, int], dict[int, float]]:
    """Each cell's episodes' mean errors by episode seed."""
    return {
        (r["task"], r["agent"], int(r["particles"])): {
            int(e["seed"]): float(e["mean_error_mm"]) for e in r["episodes"]
        }
        for r in rows
    }


def reproduction_problems(rerun: list[dict[str, Any]], recorded: list[dict[str, Any]]) -> list[str]:
    """What of ``rerun`` does not reproduce ``recorded`` within the stated tolerances.

    Args:
        rerun: The rows of the rerun (:func:`run_leaderboard`).
        recorded: The recorded rows.

    Returns:
        One line per cell or episode that differs; empty if all reproduce.
    """
    got, want = _episodes(rerun), _episodes(recorded)
    if got.keys() != want.keys():
        return [f"cells differ: rerun {sorted(got)}, recorded {sorted(want)}"]
    problems = []
    for cell, episodes in want.items():
        if got[cell].keys() != episodes.keys():
            problems.append(f"{cell}: episodes {sorted(got[cell])} vs {sorted(episodes)}")
            continue
        if cell[1] == FLOOR:
            for seed, error in episodes.items():
                if not np.isclose(got[cell][seed], error, rtol=HOLD_RTOL, atol=0.0):
                    problems.append(f"{cell} episode {seed}: {got[cell][seed]!r} vs {error!r} mm")
            continue
        mean, recorded_mean = np.mean(list(got[cell].values())), np.mean(list(episodes.values()))
        if abs(mean - recorded_mean) > FILTER_RTOL * recorded_mean:
            problems.append(
                f"{cell}: mean error {mean:.1f} mm vs recorded {recorded_mean:.1f} mm "
                f"(more than {FILTER_RTOL:.0%} apart)"
            )
    return problems


@pytest.fixture(scope="module")
def rerun() -> list[dict[str, Any]]:
    """The recorded run's config run again, with one BLAS thread as the command line does."""
    config = _recorded()["config"]
    with threadpool_limits(limits=1, user_api="blas"):
        return run_leaderboard(
            config["tasks"], config["agents"], config["particles"],
            episodes=config["episodes"], seed=config["seed"], progress=False,
        )  # fmt: skip


def test_the_recorded_table_reproduces(rerun):
    recorded = _recorded()
    assert recorded["data"] == [] and recorded["env_kwargs"].get("data_dir") is None
    assert reproduction_problems(rerun, recorded["rows"]) == []


def _scaled(rows: list[dict[str, Any]], agent: str, task: str, factor: float) -> list[dict]:
    out = json.loads(json.dumps(rows))
    for row in out:
        if row["agent"] == agent and row["task"] == task:
            for episode in row["episodes"][:1] if agent == FLOOR else row["episodes"]:
                episode["mean_error_mm"] *= factor
    return out


def test_the_comparison_fails_on_perturbed_records():
    """Mutations: the check sees a filter cell 30% off and one hold episode 1e-5 off."""
    rows = _recorded()["rows"]
    assert reproduction_problems(rows, rows) == []
    for factor in (1.3, 0.7):
        (line,) = reproduction_problems(rows, _scaled(rows, "pf-tree", "SideWalk-v2", factor))
        assert line.startswith("('SideWalk-v2', 'pf-tree', 100): mean error")
    (line,) = reproduction_problems(rows, _scaled(rows, FLOOR, "ArmTrack-v2", 1 + 1e-5))
    assert line.startswith("('ArmTrack-v2', 'hold', 0) episode 0:")
    assert reproduction_problems(rows, rows[1:])[0].startswith("cells differ")


def test_the_record_carries_its_platform():
    document = _recorded()
    assert document["commit"] and PLATFORM_KEYS <= document["platform"].keys()


def test_run_platform_records_versions_blas_cpu_and_threads():
    found = run_platform()
    assert PLATFORM_KEYS <= found.keys()
    assert PACKAGE_KEYS <= found["packages"].keys()
    assert found["packages"]["numpy"] == np.__version__
    assert json.loads(json.dumps(found)) == found
    # numpy's BLAS is loaded (platform_info imports numpy), so at least one is reported
    assert any(lib["user_api"] == "blas" for lib in found["blas"])
    for lib in found["blas"]:
        assert {"internal_api", "version", "num_threads"} <= lib.keys()
        # a BLAS says which kernels it runs; an OpenMP runtime loaded beside it has none
        assert lib["user_api"] != "blas" or "architecture" in lib
    threads = found["threads"]
    assert threads["blas"] == [
        lib["num_threads"] for lib in found["blas"] if lib["user_api"] == "blas"
    ]
    assert threads["numba"] >= 1 and threads["available_cores"] >= 1
    with threadpool_limits(limits=1, user_api="blas"):
        assert set(run_platform()["threads"]["blas"]) == {1}


def test_run_platform_without_torch(monkeypatch):
    """torch and stable-baselines3 absent: their versions None, no torch thread count."""
    real = importlib.metadata.version

    def version(name: str) -> str:
        if name.replace("_", "-") in ("torch", "stable-baselines3"):
            raise importlib.metadata.PackageNotFoundError(name)
        return real(name)

    monkeypatch.setattr(importlib.metadata, "version", version)
    monkeypatch.setitem(sys.modules, "torch", None)
    found = run_platform()
    assert found["packages"]["torch"] is None and found["packages"]["stable-baselines3"] is None
    assert found["threads"]["torch"] is None
    assert json.loads(json.dumps(found)) == found


def test_cpu_model_reads_cpuinfo_else_the_platform(tmp_path):
    cpuinfo = tmp_path / "cpuinfo"
    cpuinfo.write_text("processor\t: 0\nmodel\t\t: 1\nmodel name\t: Example CPU @ 3 GHz\n")
    assert platform_info.cpu_model(cpuinfo) == "Example CPU @ 3 GHz"
    cpuinfo.write_text("processor\t: 0\nHardware\t: Example SoC\n")
    assert platform_info.cpu_model(cpuinfo) == "Example SoC"
    assert isinstance(platform_info.cpu_model(tmp_path / "missing"), str)


def test_the_numbers_do_not_depend_on_the_callers_blas_threads():
    """The engine runs every episode on one BLAS thread: 1 or 2 outside give the same numbers."""
    runs = []
    for limit in (1, 2):
        with threadpool_limits(limits=limit, user_api="blas"):
            rows = run_leaderboard(["ArmTrack-v2"], ["pf-cv"], [50], episodes=2, progress=False)
        runs.append({r["agent"]: [e["errors_mm"] for e in r["episodes"]] for r in rows})
    assert runs[0] == runs[1]
