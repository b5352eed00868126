"""What a run records of its platform, and the Ray address forms, on made-up inputs."""

from __future__ import annotations

import importlib.metadata
from pathlib import Path

import pytest

from baselines.leaderboard import platform_info
from baselines.leaderboard.ray_setup import NoRayCluster, check_ray_address, check_ray_address_form

#: threadpoolctl's report of an OpenBLAS and an OpenMP runtime (which has no architecture).
POOLS = [
    {"user_api": "blas", "internal_api": "openblas", "prefix": "libopenblas", "version": "0.3.27",
     "num_threads": 2, "architecture": "Haswell", "threading_layer": "pthreads",
     "filepath": "/lib/libopenblas.so"},
    {"user_api": "openmp", "internal_api": "openmp", "prefix": "libgomp", "version": None,
     "num_threads": 8, "filepath": "/lib/libgomp.so"},
]  # fmt: skip


def test_blas_libraries_keep_the_listed_keys_each_reports(monkeypatch: pytest.MonkeyPatch) -> None:
    """Each library's reported keys of BLAS_KEYS, no others, none added as None."""
    monkeypatch.setattr(platform_info, "threadpool_info", lambda: [dict(p) for p in POOLS])
    libs = platform_info.blas_libraries()
    assert libs[0] == {k: v for k, v in POOLS[0].items() if k != "filepath"}
    assert libs[1] == {"user_api": "openmp", "internal_api": "openmp", "prefix": "libgomp",
                       "version": None, "num_threads": 8}  # fmt: skip


def test_thread_counts_are_the_blas_ones_and_the_variables_set(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """``blas``: BLAS libraries' threads only (not OpenMP's); ``environment``: the set variables."""
    monkeypatch.setattr(platform_info, "threadpool_info", lambda: [dict(p) for p in POOLS])
    monkeypatch.setenv("OMP_NUM_THREADS", "3")
    monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    monkeypatch.delenv("MKL_NUM_THREADS", raising=False)
    threads = platform_info.thread_counts()
    assert threads["blas"] == [2]
    assert threads["environment"] == {"OMP_NUM_THREADS": "3"}


def test_a_package_is_recorded_under_its_first_distribution_found(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """OpenCV's wheels in their listed order: the first installed one is recorded."""

    def version(name: str) -> str:
        if name == "opencv-python-headless":
            raise importlib.metadata.PackageNotFoundError(name)
        return f"{name} 1.0"

    monkeypatch.setattr(importlib.metadata, "version", version)
    versions = platform_info.package_versions()
    assert versions["opencv"] == "opencv-python 1.0"  # not the contrib wheels listed after it
    assert versions["stable-baselines3"] == "stable-baselines3 1.0"


def test_an_empty_model_name_is_passed_over(tmp_path: Path) -> None:
    """A field present but empty does not name the CPU: the next field does."""
    cpuinfo = tmp_path / "cpuinfo"
    cpuinfo.write_text("processor\t: 0\nmodel name\t:\nHardware\t: Example SoC\n")
    assert platform_info.cpu_model(cpuinfo) == "Example SoC"


@pytest.mark.parametrize(
    "address, want",
    [
        ("auto", None),
        ("local", None),
        ("10.0.0.9:6379", ("10.0.0.9", 6379)),
        ("ray://head.example:10001", ("head.example", 10001)),
        ("fe80::1:6379", ("fe80::1", 6379)),  # the port after the last colon
    ],
)
def test_ray_address_forms(address: str, want: tuple[str, int] | None) -> None:
    """``auto`` and ``local`` are Ray's; else HOST:PORT, ``ray://`` taken off."""
    assert check_ray_address_form(address) == want


@pytest.mark.parametrize("address", [":6379", "head", "head:", "head:port", "ray://:10001"])
def test_ray_addresses_without_a_host_or_port_are_refused(address: str) -> None:
    """A host and a numeric port are both needed."""
    with pytest.raises(ValueError, match="expected HOST:PORT, ray://HOST:PORT, auto or local"):
        check_ray_address_form(address)


def test_a_host_name_the_resolver_refuses_is_no_cluster() -> None:
    """A name socket cannot encode (a label over 63 letters) is NoRayCluster, not a traceback."""
    with pytest.raises(NoRayCluster, match="no Ray cluster answers there"):
        check_ray_address("x" * 300 + ":6379", timeout=0.5)
