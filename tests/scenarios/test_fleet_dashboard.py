"""The fleet dashboard in a real headless browser (the system's Chromium driven by Playwright):
it loads from disk without console errors, its table has a row per robot, a robot's page shows
its history figure, and a screenshot is taken (docs/figures/fleet_dashboard.png is one).

Without Chromium or Playwright the test is skipped, except under CI (the CI environment
variable set), where it fails: .ci/run installs both."""

from __future__ import annotations

import os
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from odocal.io.fleet_db import open_db
from tests.support.fleet import fill_db

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--no-first-run"]  # fmt: skip
SE = np.array([5e-5, 5e-5, 2.5e-4])


# Chromium is a system package, which the README's test command cannot install: without it the
# browser test is skipped (a visible reason), except under CI, where .ci/run installs it and its
# absence fails (playwright, a Python package of the test extra, is always there)
HAVE_CHROMIUM = Path(CHROMIUM).is_file()
needs_chromium = pytest.mark.skipif(
    not HAVE_CHROMIUM and not os.environ.get("CI"),
    reason="chromium not installed (apt-get install chromium; .ci/run installs it)",
)


def dashboard(folder: Path) -> Path:
    """A fleet of five robots (one with a 0.6 % step of its right wheel, one whose bags are all
    calibrated but not to be trusted) and its dashboard."""
    from odocal.app.fleet_report import fleet_report

    rng = np.random.default_rng(8)
    robots = {}
    for r, step in (("tb3-001", 0.0), ("tb3-002", 0.006), ("tb3-003", 0.0), ("husky-01", 0.0)):
        true = np.array([0.066, 0.066, 0.160]) if r.startswith("tb3") else np.array(
            [0.33, 0.33, 0.555])  # fmt: skip
        se = SE * true / np.array([0.05, 0.05, 0.25])
        bags = []
        for i in range(30):
            v = true * (1 + np.array([step if i >= 22 else 0.0, 0, 0]))
            bags.append((tuple(v + se * rng.standard_normal(3)), tuple(se)))
        robots[r] = bags
    robots["tb3-004"] = robots["tb3-003"][:5]
    with open_db(folder / "fleet.db", write=True) as db:
        fill_db(db, robots, untrusted=("tb3-004",))
    return fleet_report(folder / "fleet.db", folder / "html").index


@needs_chromium
def test_the_dashboard_in_chromium(tmp_path):
    assert HAVE_CHROMIUM, "the dashboard's browser test needs chromium (.ci/run installs it)"
    from playwright.sync_api import sync_playwright

    index = dashboard(tmp_path)
    errors: list[str] = []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        page = browser.new_page(viewport={"width": 1200, "height": 700})
        page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
        page.on("pageerror", lambda e: errors.append(str(e)))
        page.on("requestfailed", lambda r: errors.append(f"failed: {r.url}"))
        page.goto(index.as_uri())
        rows = page.locator("#fleet tbody tr")
        assert rows.count() == 5
        assert rows.nth(0).locator("td").first.inner_text() == "tb3-002"  # the drift first
        assert re.search(r"wheel_diameter_right_m \+0\.[4-8]\d %", rows.nth(0).inner_text())
        # then the robot without a trusted calibration, not among the healthy ones
        assert rows.nth(1).locator("td").first.inner_text() == "tb3-004"
        assert "no trusted calibration" in rows.nth(1).inner_text()
        page.screenshot(path=str(tmp_path / "index.png"))
        page.click("text=tb3-002")
        assert page.locator("svg").count() == 1 and "Drift alarms" in page.content()
        page.locator("a:text('report')").first.click()
        assert "Odometry calibration of" in page.locator("h1").inner_text()
        assert page.locator("table").count() >= 3 and page.locator("pre").count() == 0
        browser.close()
    assert errors == []
    assert (tmp_path / "index.png").stat().st_size > 10_000
