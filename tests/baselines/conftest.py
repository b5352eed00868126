"""Fixtures shared by the tests of ``baselines``."""

from __future__ import annotations

import pytest


@pytest.fixture
def no_figures(monkeypatch: pytest.MonkeyPatch) -> None:
    """Reports written without their figures (matplotlib's PNGs, about 0.5 s a report).

    For the tests of what a page says, links or rebuilds besides its figures;
    the figures are checked where they are the subject (test_stats_report's
    test_report_writes_tables_figures_and_a_page_whose_links_exist and
    test_report_renders_in_headless_chromium).
    """
    import baselines.leaderboard.report as report

    monkeypatch.setattr(report, "figures_available", lambda: False)
