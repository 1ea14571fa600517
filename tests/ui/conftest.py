"""Browser fixtures of the UI tests: the app on spot in a background thread, Debian's chromium
driven headless by Playwright.

Only tests marked ``browser`` use them. A missing chromium or Playwright is an error of those
tests (they fail, loudly), never a skip; no other test needs a browser.
"""

from __future__ import annotations

import shutil
import time
from pathlib import Path

import pytest

CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--enable-unsafe-swiftshader",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-default-apps",
    "--disable-sync",
    "--no-first-run",
    "--metrics-recording-only",
]
VIEWPORT = {"width": 1000, "height": 700}


def pytest_configure(config) -> None:
    config.addinivalue_line(
        "markers", "browser: drives the web app in Debian's chromium (fails if it is missing)"
    )


@pytest.fixture(scope="module")
def browser():
    if not CHROMIUM.exists():
        pytest.fail(
            f"browser tests need Debian's chromium at {CHROMIUM} (apt-get install chromium)"
        )
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        yield b
        b.close()


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    return tmp_path_factory.mktemp("ui-work")


@pytest.fixture(scope="module")
def app(workdir):
    from meshfit.ui.app import App
    from meshfit.ui.files import FilePolicy
    from meshfit.ui.state import Session
    from tests.conftest import real_mesh

    session = Session(real_mesh("spot"), autosave=workdir / "spot.session.json")
    a = App(session, FilePolicy(workdir), host="127.0.0.1", port=0)
    yield a
    a.stop()


@pytest.fixture(scope="module")
def page(browser, app):
    pg = browser.new_page(viewport=VIEWPORT)
    pg.goto(f"http://127.0.0.1:{app.port}/")
    pg.get_by_role("button", name="Finish curve").wait_for(timeout=60_000)
    time.sleep(1.5)  # first frames of the software renderer
    yield pg
    pg.close()


def wait_for(cond, timeout: float = 30.0, what: str = "condition") -> None:
    """Poll ``cond()`` until true (server-side state follows browser events asynchronously)."""
    t0 = time.monotonic()
    while not cond():
        if time.monotonic() - t0 > timeout:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.05)


def have_chromium() -> bool:
    return CHROMIUM.exists() or shutil.which("chromium") is not None
