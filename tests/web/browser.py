"""Shared by the browser tests: Debian's Chromium driven by Playwright, one window per page."""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_ARGS = [
    "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
]
ARTIFACTS = Path(__file__).resolve().parents[2] / "test-artifacts" / "web"
TIMEOUT_MS = 20_000
TABLET_PORTRAIT = {"width": 768, "height": 1024}


class Windows:
    """Each page in its own browser context (its own window and session storage)."""

    def __init__(self, browser: Any) -> None:
        self.browser = browser

    def new_page(self, viewport: dict[str, int] | None = None) -> Any:
        context = self.browser.new_context(viewport=viewport or {"width": 1280, "height": 720})
        context.set_default_timeout(TIMEOUT_MS)
        return context.new_page()


@contextmanager
def chromium(sync_api: Any) -> Iterator[Windows]:
    with sync_api.sync_playwright() as playwright:
        launched = playwright.chromium.launch(
            executable_path=str(CHROMIUM), headless=True, args=CHROMIUM_ARGS
        )
        try:
            yield Windows(launched)
        finally:
            launched.close()


def contrast(first: str, second: str) -> float:
    """WCAG 2 contrast ratio of two CSS colours given as ``rgb(r, g, b)`` (or ``rgba``)."""

    def luminance(css: str) -> float:
        r, g, b = (float(v) for v in css[css.index("(") + 1:css.index(")")].split(",")[:3])
        linear = [
            c / 255 / 12.92 if c / 255 <= 0.04045 else ((c / 255 + 0.055) / 1.055) ** 2.4 for c in (r, g, b)
        ]
        return 0.2126 * linear[0] + 0.7152 * linear[1] + 0.0722 * linear[2]

    high, low = sorted((luminance(first), luminance(second)), reverse=True)
    return (high + 0.05) / (low + 0.05)


def screenshot(page: Any, name: str, **options: Any) -> None:
    """Save a screenshot under ``test-artifacts/web/``; with ``BOWDEN_DOC_SCREENSHOTS=DIR`` also in DIR
    (``docs/images/web`` holds the ones docs/web.md shows)."""
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(ARTIFACTS / name), **options)
    docs = os.environ.get("BOWDEN_DOC_SCREENSHOTS")
    if docs:
        Path(docs).mkdir(parents=True, exist_ok=True)
        shutil.copyfile(ARTIFACTS / name, Path(docs) / name)
