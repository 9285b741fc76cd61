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


def overflowing_tables(report: Path, sync_api: Any) -> tuple[list[str], float]:
    """Captions of tables wider than the body and not in a scrolling box; the page's horizontal overflow."""
    with sync_api.sync_playwright() as playwright:
        browser = playwright.chromium.launch(
            executable_path=str(CHROMIUM), headless=True, args=["--no-sandbox", "--disable-gpu"]
        )
        try:
            page = browser.new_context(viewport=VIEWPORT).new_page()
            page.goto(report.resolve().as_uri())
            tables = page.evaluate(_MEASURE)
            overflow = page.evaluate("() => document.documentElement.scrollWidth - window.innerWidth")
        finally:
            browser.close()
    bad = [t["caption"] for t in tables if t["width"] > t["content"] + 1 and not t["scrolls"]]
    return bad, float(overflow)
