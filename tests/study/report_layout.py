"""The report in Chromium: which tables are wider than the page and do not scroll in their own box."""

from __future__ import annotations

from pathlib import Path
from typing import Any

CHROMIUM = Path("/usr/bin/chromium")
VIEWPORT = {"width": 1280, "height": 900}

# For each table: its caption, its width, the width of the body's content box, and whether it sits in
# a box of its own that scrolls horizontally and is no wider than the body.
_MEASURE = """() => {
  const body = document.body, bodyStyle = getComputedStyle(body);
  const content = body.clientWidth - parseFloat(bodyStyle.paddingLeft) - parseFloat(bodyStyle.paddingRight);
  return [...document.querySelectorAll('table')].map(table => {
    const box = table.parentElement, style = getComputedStyle(box);
    const scrolls = ['auto', 'scroll'].includes(style.overflowX) && box.clientWidth <= content + 1;
    const caption = table.querySelector('caption');
    return {caption: caption ? caption.textContent : '(no caption)',
            width: table.getBoundingClientRect().width, content: content, scrolls: scrolls};
  });
}"""


def overflowing_tables(reports: list[Path], sync_api: Any) -> list[tuple[list[str], float]]:
    """Per report: the captions of tables wider than the body and not in a scrolling box, and the
    page's horizontal overflow. One Chromium for them all (its launch is most of the CPU: 1.6 s)."""
    with sync_api.sync_playwright() as playwright:
        browser = playwright.chromium.launch(
            executable_path=str(CHROMIUM), headless=True, args=["--no-sandbox", "--disable-gpu"]
        )
        try:
            return [_measure(browser, report) for report in reports]
        finally:
            browser.close()


def _measure(browser: Any, report: Path) -> tuple[list[str], float]:
    page = browser.new_context(viewport=VIEWPORT).new_page()
    page.goto(report.resolve().as_uri())
    tables = page.evaluate(_MEASURE)
    overflow = page.evaluate("() => document.documentElement.scrollWidth - window.innerWidth")
    bad = [t["caption"] for t in tables if t["width"] > t["content"] + 1 and not t["scrolls"]]
    return bad, float(overflow)
