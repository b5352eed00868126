"""The platform a leaderboard ran on, as ``results.json`` records it.

A particle filter's last bits depend on the CPU (numpy and OpenBLAS pick their
SIMD code by CPU), the BLAS and its thread count: :func:`run_platform` records
what tells why two runs differ.
"""

from __future__ import annotations

import importlib.metadata
import os
import platform
import sys
from pathlib import Path
from typing import Any

import numpy as np  # noqa: F401  (loaded so that threadpoolctl sees numpy's BLAS)
from threadpoolctl import threadpool_info

from humotion_gym.threads import THREAD_ENV_VARS, available_cores

#: Distributions whose versions are recorded, by the name they are reported
#: under, each with its distribution names in turn (OpenCV ships as several wheels).
PACKAGES: dict[str, tuple[str, ...]] = {
    "numpy": ("numpy",),
    "scipy": ("scipy",),
    "numba": ("numba",),
    "opencv": (
        "opencv-python-headless", "opencv-python",
        "opencv-contrib-python-headless", "opencv-contrib-python",
    ),
    "gymnasium": ("gymnasium",),
    "threadpoolctl": ("threadpoolctl",),
    "torch": ("torch",),
    "stable-baselines3": ("stable-baselines3", "stable_baselines3"),
    "ray": ("ray",),
}  # fmt: skip
#: The keys of each BLAS (or OpenMP) library :func:`threadpool_info` reports that are kept.
BLAS_KEYS: tuple[str, ...] = (
    "user_api", "internal_api", "prefix", "version", "num_threads", "architecture",
    "threading_layer",
)  # fmt: skip


def package_versions() -> dict[str, str | None]:
    """The installed version of each of :data:`PACKAGES` and of Python (None where absent).

    Read from the distributions' metadata: nothing is imported.
    """
    versions: dict[str, str | None] = {"python": platform.python_version()}
    for name, distributions in PACKAGES.items():
        versions[name] = None
        for distribution in distributions:
            try:
                versions[name] = importlib.metadata.version(distribution)
                break
            except importlib.metadata.PackageNotFoundError:
                continue
    return versions


def cpu_model(cpuinfo: str | Path = "/proc/cpuinfo") -> str:
    """The CPU's model name: ``cpuinfo``'s where it exists, else :func:`platform.processor`.

    Returns:
        The model name ("" where the platform does not tell it).
    """
    try:
        text = Path(cpuinfo).read_text(errors="replace")
    except OSError:
        text = ""
    fields: dict[str, str] = {}
    for line in text.splitlines():
        key, _, value = line.partition(":")
        fields.setdefault(key.strip().lower(), value.strip())
    # x86 says "model name" (its "model" is a number); ARM kernels "Model" or "Hardware"
    for key in ("model name", "cpu model", "hardware", "model"):
        if fields.get(key):
            return fields[key]
    return platform.processor() or platform.machine()


def blas_libraries() -> list[dict[str, Any]]:
    """The BLAS and OpenMP libraries loaded, as :func:`threadpoolctl.threadpool_info` has them.

    Each with the keys of :data:`BLAS_KEYS` it has (``num_threads``: what it would use now).
    """
    return [{k: lib.get(k) for k in BLAS_KEYS if k in lib} for lib in threadpool_info()]


def thread_counts() -> dict[str, Any]:
    """The threads this process computes with.

    ``blas``: each loaded BLAS library's; ``numba``: its pool's; ``torch``: its
    intra-op threads where torch is loaded (else None); ``environment``: the
    variables of :data:`THREAD_ENV_VARS` set; ``available_cores``.
    """
    import numba

    torch = sys.modules.get("torch")
    return {
        "blas": [lib.get("num_threads") for lib in threadpool_info() if lib["user_api"] == "blas"],
        "numba": int(numba.config.NUMBA_NUM_THREADS),  # type: ignore[attr-defined]
        "torch": int(torch.get_num_threads()) if torch is not None else None,
        "environment": {k: os.environ[k] for k in THREAD_ENV_VARS if k in os.environ},
        "available_cores": available_cores(),
    }


def run_platform() -> dict[str, Any]:
    """What ``results.json`` records of the machine and software a run used.

    Returns:
        A JSON-serialisable dict: ``packages`` (:func:`package_versions`),
        ``platform`` (:func:`platform.platform`), ``machine``, ``cpu``
        (:func:`cpu_model`), ``cpu_count`` (:func:`os.cpu_count`), ``blas``
        (:func:`blas_libraries`) and ``threads`` (:func:`thread_counts`). The
        thread counts are the writing process's; a Ray run's workers track
        with one BLAS thread each (docs/leaderboard.md).
    """
    return {
        "packages": package_versions(),
        "platform": platform.platform(),
        "machine": platform.machine(),
        "cpu": cpu_model(),
        "cpu_count": os.cpu_count(),
        "blas": blas_libraries(),
        "threads": thread_counts(),
    }
