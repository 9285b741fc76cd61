"""Benchmark: latency from a sample in the control loop to its pixels on the participant display.

A simulated trial runs in real time (500 Hz loop, ``bowden serve``'s server in a thread) while
Debian's Chromium shows ``/display`` headless, driven by Playwright. Every row the loop hands to the
web tap is stamped with the wall clock (``time.time()``); the display records, for every sample it
draws, the end of the frame that drew it and the start of the next animation frame (the moment the
drawn frame was handed to the screen: ``performance.timeOrigin`` + the ``requestAnimationFrame``
timestamp). The browser's clock is aligned to Python's by the round trip with the smallest delay
(the offset's uncertainty, half that round trip, is printed).

Latency = presented − stamp, per sample shown. Target (issue 9): p95 ≤ 50 ms here; also the display's
frame rate (target ≥ 30 fps). Prints figures and their ratios to the targets; no assertion.

Usage: ``python benchmarks/web_latency.py [--speed V2] [--repetitions 3] [--console]``
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
import urllib.request
from pathlib import Path

from playwright.sync_api import Page, sync_playwright

from bowden.model import CompensationModel
from bowden.web.server import ServeConfig, ServerThread
from bowden.web.suits import SimulatedBackend

TARGET_P95_MS = 50.0
TARGET_FPS = 30.0
CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
]


def clock_offset_ms(page: Page, rounds: int = 30) -> tuple[float, float]:
    """Browser epoch ms minus Python epoch ms, and half the round trip it was measured with."""
    best = (0.0, float("inf"))
    for _ in range(rounds):
        before = 1e3 * time.time()
        browser = float(page.evaluate("() => performance.timeOrigin + performance.now()"))
        after = 1e3 * time.time()
        half = 0.5 * (after - before)
        if half < best[1]:
            best = (browser - 0.5 * (before + after), half)
    return best


def post(url: str, token: str, body: dict[str, object]) -> dict[str, object]:
    request = urllib.request.Request(
        url, data=json.dumps(body).encode(), method="POST",
        headers={"Content-Type": "application/json", "X-Bowden-Token": token},
    )
    with urllib.request.urlopen(request, timeout=10) as response:
        result: dict[str, object] = json.loads(response.read())
        return result


def percentile(values: list[float], fraction: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(fraction * len(ordered)))]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--speed", default="V2", choices=("V1", "V2", "V3"))
    parser.add_argument("--repetitions", type=int, default=3)
    parser.add_argument("--rate-hz", type=float, default=500.0)
    parser.add_argument("--console", action="store_true", help="also keep the operator console open")
    args = parser.parse_args()

    with tempfile.TemporaryDirectory() as folder:
        config = ServeConfig(
            store_path=Path(folder) / "study.sqlite",
            model=CompensationModel.from_friction(k=0.12),
            backend=SimulatedBackend(time_scale=1.0),
            port=0,
            rate_hz=args.rate_hz,
        )
        with ServerThread(config) as server, sync_playwright() as playwright:
            token = server.web.token.value
            # Playwright gives the browser a fresh temporary profile; each page gets its own context
            # (its own window), as the display and the console have their own screens in the lab.
            # Two tabs of one window would not do: the hidden tab's animation frames are throttled.
            browser = playwright.chromium.launch(executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS)
            viewport = {"width": 1280, "height": 720}
            display = browser.new_context(viewport=viewport).new_page()
            display.goto(f"{server.url}/display")
            display.wait_for_function("() => window.bowdenDisplay && bowdenDisplay.connected()")
            if args.console:
                console = browser.new_context(viewport=viewport).new_page()
                console.goto(f"{server.url}/console#token={token}")
            offset_ms, offset_error_ms = clock_offset_ms(display)
            started = post(f"{server.url}/api/trial/start", token, {
                "participant": "P01", "condition": "support_50", "speed": args.speed,
                "repetitions": args.repetitions, "height_m": 1.70, "mass_kg": 63.0, "sex": "female",
            })
            display.wait_for_function("() => bowdenDisplay.running()")
            wall_start = time.perf_counter()
            display.wait_for_function("() => !bowdenDisplay.running()", timeout=300_000)
            wall_s = time.perf_counter() - wall_start
            fps = float(display.evaluate("() => bowdenDisplay.framesPerSecond()"))
            records = display.evaluate("() => bowdenDisplay.latency()")
            trace_points = int(display.evaluate("() => bowdenDisplay.trace().length"))
            browser.close()
        result = server.web.manager.last_result or {}

    presented = [r["presented_ms"] - offset_ms - r["stamp_ms"] for r in records]
    drawn = [r["drawn_ms"] - offset_ms - r["stamp_ms"] for r in records]
    p95 = percentile(presented, 0.95)
    print(f"trial {started.get('trial_id')}: {args.speed}, {args.repetitions} repetitions, "
          f"{args.rate_hz:g} Hz loop, {wall_s:.1f} s wall; {result.get('timing', '')}")
    print(f"clock offset browser - python {offset_ms:+.2f} ms (± {offset_error_ms:.2f} ms)")
    print(f"samples drawn: {len(records)} with latency records, {trace_points} in the trace")
    for name, values in (("loop -> drawn", drawn), ("loop -> presented", presented)):
        print(f"{name:18s} p50 {percentile(values, 0.5):6.1f} ms  p95 {percentile(values, 0.95):6.1f} ms  "
              f"p99 {percentile(values, 0.99):6.1f} ms  max {max(values):6.1f} ms  "
              f"mean {statistics.fmean(values):6.1f} ms")
    print(f"display frame rate: {fps:.1f} fps")
    print(f"ratio p95 / target ({TARGET_P95_MS:g} ms): {p95 / TARGET_P95_MS:.2f}  "
          f"({'met' if p95 <= TARGET_P95_MS else 'NOT met'})")
    print(f"ratio fps / target ({TARGET_FPS:g} fps): {fps / TARGET_FPS:.2f}  "
          f"({'met' if fps >= TARGET_FPS else 'NOT met'})")


if __name__ == "__main__":
    main()
