"""End to end in a real browser: Debian's Chromium, headless, driven by Playwright.

The server runs in a thread on a free loopback port with the simulated suit in real time. Screenshots
of the display, the console and the questionnaire are saved under ``test-artifacts/web/``.
Playwright cannot download its own browsers here, so Debian's ``/usr/bin/chromium`` is launched
(``.ci/run`` installs it); without it these tests are skipped.
"""

from __future__ import annotations

import math
import re
import sqlite3
import sys
from collections.abc import Iterator
from contextlib import ExitStack
from pathlib import Path

import pytest

from bowden.cli import build_parser
from bowden.cli.serve import serve_config, synced
from bowden.contracts import FATIGUE_SITES, NORDIC_SITES
from bowden.model import CompensationModel
from bowden.store.sample_chunks import read_samples
from bowden.web.server import ServeConfig, ServerThread
from bowden.web.suits import SimulatedBackend
from bowden.web.trial_setup import parse_setup

from .conftest import TOKEN, WireSuit, assert_safe_state_after, store_snapshot, trial_request

sync_api = pytest.importorskip("playwright.sync_api")
CHROMIUM = Path("/usr/bin/chromium")
pytestmark = pytest.mark.skipif(not CHROMIUM.exists(), reason="Debian's chromium is not installed")
CHROMIUM_ARGS = [
    "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
]
ARTIFACTS = Path(__file__).resolve().parents[2] / "test-artifacts" / "web"
TIMEOUT_MS = 20_000
TRIGGER_LOG = Path(__file__).parents[1] / "runtime" / "trigger_log.py"


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ServerThread]:
    config = ServeConfig(
        store_path=tmp_path_factory.mktemp("web") / "study.sqlite",
        model=CompensationModel.from_friction(k=0.12),
        backend=SimulatedBackend(time_scale=1.0),
        port=0,
        token=TOKEN,
    )
    with ServerThread(config) as running:
        yield running


class Windows:
    """Each page in its own browser context (its own window and session storage, like separate screens
    in the lab); Playwright launches the browser with a fresh temporary profile."""

    def __init__(self, browser: object) -> None:
        self.browser = browser

    def new_page(self) -> object:
        context = self.browser.new_context(viewport={"width": 1280, "height": 720})
        context.set_default_timeout(TIMEOUT_MS)
        return context.new_page()


@pytest.fixture(scope="module")
def browser() -> Iterator[Windows]:
    with sync_api.sync_playwright() as playwright:
        chromium = playwright.chromium.launch(
            executable_path=str(CHROMIUM), headless=True, args=CHROMIUM_ARGS
        )
        try:
            yield Windows(chromium)
        finally:
            chromium.close()


def stored_samples(path: Path, trial_id: int) -> dict[float, float]:
    with sqlite3.connect(path) as connection:
        rows = read_samples(connection, trial_id).loc[:, ["time_s", "elevation_rad"]]
    return {round(t, 4): math.degrees(el) for t, el in rows.itertuples(index=False, name=None)}


def test_an_operator_action_without_the_token_is_refused_and_changes_nothing(server, browser):
    path = server.web.config.store_path
    before = store_snapshot(path)
    console = browser.new_page()
    console.goto(f"{server.url}/console")  # no token in the URL, none stored in this tab
    console.wait_for_function("() => document.getElementById('condition').options.length === 4")
    assert console.locator("#connection").inner_text() == "no token"
    console.fill("#participant", "P21")
    console.click("#start")
    console.wait_for_function("() => document.getElementById('message').textContent.includes('token')")
    assert "nothing was changed" in console.inner_text("#message")
    console.click("#stop")
    console.wait_for_function("() => document.getElementById('message').textContent.includes('token')")
    status = console.evaluate(
        """async () => (await fetch('/api/questionnaires', {method: 'POST',
             headers: {'Content-Type': 'application/json', 'X-Bowden-Token': 'guessed-guessed-guessed'},
             body: JSON.stringify({participant: 'P21', condition: 'no_suit'})})).status"""
    )
    assert status == 403
    assert store_snapshot(path) == before
    assert not server.web.manager.running and server.web.manager.trials_run == 0
    console.context.close()


def test_the_display_trace_follows_a_simulated_trial(server, browser):
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    display = browser.new_page()
    display.goto(f"{server.url}/display")
    display.wait_for_function("() => window.bowdenDisplay && bowdenDisplay.connected()")
    # Read-only: nothing on the page can be clicked or typed into.
    assert display.locator("button, input, select, textarea, a").count() == 0
    assert display.eval_on_selector("#display", "c => getComputedStyle(c).pointerEvents") == "none"

    console = browser.new_page()
    console.goto(f"{server.url}/console#token={TOKEN}")
    assert "token" not in console.url  # the token left the address bar
    console.wait_for_function("() => document.getElementById('connection').textContent === 'live'")
    console.fill("#participant", "P11")
    console.select_option("#condition", "support_50")
    console.select_option("#speed", "V3")
    console.fill("#repetitions", "1")
    console.click("#start")
    display.wait_for_function("() => bowdenDisplay.running() && bowdenDisplay.lastT() > 2.6")
    display.screenshot(path=str(ARTIFACTS / "display.png"))
    console.screenshot(path=str(ARTIFACTS / "console.png"), full_page=True)
    display.wait_for_function("() => !bowdenDisplay.running()")
    console.wait_for_function(
        "() => document.getElementById('last-result').textContent.includes('completed')"
    )
    assert "duration" in console.inner_text("#last-result")
    display.screenshot(path=str(ARTIFACTS / "display-end.png"))

    manager = server.web.manager
    result = manager.last_result
    assert result is not None and result["clean"]
    trial_id = int(result["trial_id"])
    stored = stored_samples(server.web.config.store_path, trial_id)
    trace = display.evaluate("bowdenDisplay.trace()")
    # Every point drawn is a recorded sample, and the drawn trace covers the whole trial at 100 Hz.
    for t, elevation in trace:
        assert elevation == pytest.approx(stored[round(t, 4)], abs=1e-3)
    setup = parse_setup(trial_request(participant="P11", speed="V3", repetitions=1, lead_in_s=2.0))
    duration = setup.duration_s
    assert trace[0][0] < 0.05 and trace[-1][0] > duration - 0.05
    assert len(trace) == pytest.approx(100 * duration, rel=0.03)
    # The trace follows the movement: it rises from 20° to near 100° and comes back.
    elevations = [el for _, el in trace]
    assert elevations[0] == pytest.approx(20.0, abs=3.0) and max(elevations) > 85.0
    assert elevations[-1] == pytest.approx(20.0, abs=5.0)

    # The display draws the same reference as the server records.
    reference = setup.reference
    assert display.evaluate("bowdenDisplay.reference()") == pytest.approx(reference.to_json())
    times = [0.1 * k for k in range(60)]
    drawn = display.evaluate(
        "times => times.map(t => BowdenReference.elevationDeg(bowdenDisplay.reference(), t))", times
    )
    expected = [math.degrees(reference.elevation_rad(t)) for t in times]
    assert drawn == pytest.approx(expected, abs=1e-9)
    reps = display.evaluate(
        "times => times.map(t => BowdenReference.repetition(bowdenDisplay.reference(), t))", times
    )
    assert reps == [reference.repetition(t) for t in times]
    assert display.evaluate("bowdenDisplay.headline()") == "Done: 1 of 1 — rest"

    # The pixels: the measured colour under the newest sample, the reference colour ahead of it.
    last_t, last_el = trace[-1]
    colours = display.evaluate(
        """([t, el]) => {
             const ctx = document.getElementById('display').getContext('2d');
             const pick = (x, y) => Array.from(ctx.getImageData(Math.round(x), Math.round(y), 1, 1).data);
             const [x0, y0] = bowdenDisplay.toCanvas(t, el);
             const [x1, y1] = bowdenDisplay.toCanvas(t + 2.0, 20.0);
             return [pick(x0, y0), pick(x1, y1)];
           }""",
        [last_t, last_el],
    )
    assert colours[0][:3] == [0xFF, 0xB0, 0x20]  # measured
    assert colours[1][:3] == [0x4F, 0xA3, 0xFF]  # reference
    display.context.close()
    console.context.close()


def test_a_questionnaire_submitted_through_the_form_is_in_the_store(server, browser):
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    page = browser.new_page()
    page.goto(f"{server.url}/questionnaire#token={TOKEN}")
    radios = 16 * 7 + 15 + 6 * 7  # Nordic, Borg 6-20, fatigue
    page.wait_for_function(f"() => document.querySelectorAll('input[type=radio]').length === {radios}")
    page.fill("#participant", "P12")
    page.select_option("#condition", "support_25")
    nordic = {site: 1 + i % 7 for i, site in enumerate(NORDIC_SITES)}
    fatigue = {site: 7 - i for i, site in enumerate(FATIGUE_SITES)}
    for site, score in nordic.items():
        page.locator(f"[id='nordic.{site}-{score}']").check()
    page.locator("[id='borg_rpe-13']").check()
    for site, score in fatigue.items():
        page.locator(f"[id='fatigue.{site}-{score}']").check()
    page.screenshot(path=str(ARTIFACTS / "questionnaire.png"), full_page=True)
    page.click("#submit")  # P12 ran no trial: refused until the operator marks an exception
    page.wait_for_function("() => document.getElementById('message').textContent.includes('has not run')")
    page.fill("#exception", "checking the form before the study")
    page.click("#submit")
    page.wait_for_function("() => document.getElementById('message').textContent.startsWith('Stored')")
    assert page.inner_text("#message") == "Stored 23 answers of P12 after support_25."

    rows = server.web.questionnaires.rows("P12", "support_25")
    stored = {(q, item): score for _, _, q, item, score, _ in rows}
    assert len(stored) == 23 and stored[("borg_rpe", "rpe")] == 13
    assert all(stored[("nordic", s)] == v for s, v in nordic.items())
    assert all(stored[("fatigue", s)] == v for s, v in fatigue.items())

    # Submitting the same again is refused on the page and leaves the store as it was.
    before = store_snapshot(server.web.config.store_path)
    for site, score in nordic.items():
        page.locator(f"[id='nordic.{site}-{score}']").check()
    page.locator("[id='borg_rpe-20']").check()
    for site, score in fatigue.items():
        page.locator(f"[id='fatigue.{site}-{score}']").check()
    page.fill("#exception", "checking the form before the study")
    page.click("#submit")
    page.wait_for_function("() => document.getElementById('message').textContent.includes('already stored')")
    assert store_snapshot(server.web.config.store_path) == before
    page.context.close()


def test_the_console_says_how_long_each_trigger_edge_took(browser: Windows, tmp_path: Path) -> None:
    """``bowden serve --trigger command:...``: the trial's result names its edges and warns (a slow line)."""
    levels = tmp_path / "levels.txt"
    trigger = f"command:{sys.executable} {TRIGGER_LOG} {levels} {{level}}"
    args = build_parser().parse_args(["serve", "--store", str(tmp_path / "study.db"), "--port", "0",
                                      "--rate-hz", "250", "--trigger", trigger])
    with ExitStack() as stack, ServerThread(synced(serve_config(args), args, stack)) as server:
        console = browser.new_page()
        console.goto(f"{server.url}/console#token={server.web.token.value}")
        console.wait_for_function("() => document.getElementById('connection').textContent === 'live'")
        console.fill("#participant", "P32")
        console.select_option("#condition", "support_25")
        console.select_option("#speed", "V3")
        console.fill("#repetitions", "1")
        console.click("#start")
        console.wait_for_function(
            "() => document.getElementById('last-result').textContent.includes('completed')")
        result = console.inner_text("#last-result")
        console.context.close()
    edges = r"sync: trigger edges sent: start within [\d.]+ ms, end within [\d.]+ ms"
    assert re.search(edges, result), result
    assert "sync: warning: a trigger edge took" in result  # a Python program is slower than the 2 ms budget
    assert [line.split()[0] for line in levels.read_text().splitlines()] == ["1", "0"]


def test_the_console_stop_button_puts_the_real_suit_in_its_safe_state(
    wire_suit: WireSuit, browser: Windows, tmp_path: Path
) -> None:
    """``bowden serve --backend can``: a trial started and stopped by clicking in the console."""
    args = build_parser().parse_args(["serve", *wire_suit.args(), "--store", str(tmp_path / "study.sqlite"),
                                      "--port", "0", "--rate-hz", "250"])
    with ServerThread(serve_config(args)) as server:
        console = browser.new_page()
        console.goto(f"{server.url}/console#token={server.web.token.value}")
        console.wait_for_function("() => document.getElementById('connection').textContent === 'live'")
        console.fill("#participant", "P31")
        console.select_option("#condition", "support_25")
        console.select_option("#speed", "V2")
        console.click("#start")  # the arm hangs still for the IMU calibration meanwhile
        console.wait_for_function("() => document.getElementById('trial-state').textContent === 'running'")
        wire_suit.imu.hold_arm_down(False)
        console.wait_for_function("() => Number(document.getElementById('h-cycles').textContent) > 100")
        assert console.inner_text("#h-suit").startswith("AK60-6 id 1 on virtual:")
        assert wire_suit.motor.in_motor_mode
        since = len(wire_suit.frames())
        console.click("#stop")
        console.wait_for_function("() => document.getElementById('h-state').textContent === 'safe (ended)'")
        assert "operator stop (console)" in console.inner_text("#last-result")
        ARTIFACTS.mkdir(parents=True, exist_ok=True)
        console.screenshot(path=str(ARTIFACTS / "console-real-suit.png"), full_page=True)
        console.context.close()
    assert not wire_suit.motor.in_motor_mode
    assert_safe_state_after(wire_suit.frames(), since)
