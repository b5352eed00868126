"""Tests that need an optional extra skip without it; CI installs every extra.

The skips (``pytest.importorskip``) keep ``pip install -e '.[test]'`` green;
this test keeps CI from hiding the tests they guard.
"""

from __future__ import annotations

import importlib
import os

import pytest

#: What the README's test command installs beyond the test extra, by extra.
EXTRA_MODULES = {"torch": "rl", "stable_baselines3": "rl", "ray": "distributed"}


@pytest.mark.skipif(os.environ.get("CI") != "true", reason="only CI must have every extra")
@pytest.mark.parametrize("module", sorted(EXTRA_MODULES))
def test_ci_installs_every_extra(module: str) -> None:
    importlib.import_module(module)
