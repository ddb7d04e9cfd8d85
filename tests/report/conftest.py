"""The report's fixtures: a synthetic run directory with every kind of data, and a headless
Chromium (Debian's ``chromium`` package, driven by playwright) that opens a page from file://."""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
from report_runs import write_full_run, write_scenes_only_run


@pytest.fixture
def full_run(tmp_path: Path) -> Path:
    pytest.importorskip("zarr")
    pytest.importorskip("av")
    return write_full_run(tmp_path / "full" / "run")


@pytest.fixture
def scenes_only_run(tmp_path: Path) -> Path:
    return write_scenes_only_run(tmp_path / "scenes_only" / "run")


# --------------------------------------------------------------------------------------------
# Headless Chromium


def chromium_executable() -> str:
    """The system's Chromium (``FACTORY_CHROMIUM`` overrides); fails the test naming the fix."""
    path = (
        os.environ.get("FACTORY_CHROMIUM")
        or shutil.which("chromium")
        or shutil.which("chromium-browser")
    )
    if not path:
        pytest.fail(
            "headless Chromium not found: run `bash scripts/setup.sh` (installs Debian's "
            "chromium package) or set FACTORY_CHROMIUM=/path/to/chromium"
        )
    return path


@dataclass
class PageCheck:
    """What the browser saw on a page.

    Attributes:
        console_errors: console messages of type error; page_errors: uncaught exceptions;
        failed: requests that failed; external: requests to anything but file: and data:
        (blocked); sections: ids of the page's ``<section>`` elements; images: one dict per
        ``<img>`` (``src`` prefix, ``complete``, ``naturalWidth``); title: the document title.
    """

    console_errors: list[str] = field(default_factory=list)
    page_errors: list[str] = field(default_factory=list)
    failed: list[str] = field(default_factory=list)
    external: list[str] = field(default_factory=list)
    sections: list[str] = field(default_factory=list)
    images: list[dict[str, Any]] = field(default_factory=list)
    title: str = ""
    text: str = ""


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    """A headless Chromium (the system's, via playwright), shared by a module's tests.

    Module scope, not session: playwright's sync API keeps an event loop running in the main
    thread while it is open, and later tests that call ``asyncio.run`` (the MCP client) would
    fail with "cannot be called from a running event loop"."""
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        pytest.fail("playwright is missing: run `bash scripts/setup.sh` (the dev extra has it)")
    exe = chromium_executable()
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=exe, headless=True)
        try:
            yield b
        finally:
            b.close()


@pytest.fixture
def open_page(browser: Any):
    """``open_page(path, screenshot=None) -> PageCheck``: loads a file:// page and checks it."""

    def _open(path: Path, screenshot: Path | None = None) -> PageCheck:
        check = PageCheck()
        page = browser.new_page(viewport={"width": 1280, "height": 1600})

        def route(r: Any) -> None:
            url = r.request.url
            if url.startswith(("file:", "data:")):
                r.continue_()
            else:
                check.external.append(url)
                r.abort()

        page.route("**/*", route)
        page.on(
            "console",
            lambda m: check.console_errors.append(m.text) if m.type == "error" else None,
        )
        page.on("pageerror", lambda e: check.page_errors.append(str(e)))
        page.on("requestfailed", lambda r: check.failed.append(f"{r.url[:120]}: {r.failure}"))
        try:
            page.goto(path.resolve().as_uri(), wait_until="load")
            check.title = page.title()
            check.sections = page.eval_on_selector_all("section", "els => els.map(e => e.id)")
            check.images = page.eval_on_selector_all(
                "img",
                "els => els.map(i => ({src: i.getAttribute('src').slice(0, 60), "
                "complete: i.complete, naturalWidth: i.naturalWidth}))",
            )
            check.text = page.inner_text("body")
            if screenshot is not None:
                page.screenshot(path=str(screenshot), full_page=True)
        finally:
            page.close()
        return check

    return _open
