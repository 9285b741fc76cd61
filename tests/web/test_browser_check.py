"""The defects of the browser check that need a browser, each shown fixed in Debian's Chromium.

STOP that fails on the network, STOP by Escape, a console reloaded mid-trial, the display after a
STOP, a stale token after a server restart, and the portrait tablet (headline, grid labels, touch
targets, focus ring, disabled contrast, named plots). Screenshots go to ``test-artifacts/web/``.
"""

from __future__ import annotations

import re
from collections.abc import Iterator

import pytest

from bowden.model import CompensationModel
from bowden.web.server import ServeConfig, ServerThread
from bowden.web.suits import SimulatedBackend

from .browser import CHROMIUM, TABLET_PORTRAIT, Windows, chromium, contrast, screenshot
from .conftest import SHORT_PROTOCOL, TOKEN

sync_api = pytest.importorskip("playwright.sync_api")
pytestmark = pytest.mark.skipif(not CHROMIUM.exists(), reason="Debian's chromium is not installed")
REFERENCE_RGB = (0x4F, 0xA3, 0xFF)
MEASURED_RGB = (0xFF, 0xB0, 0x20)


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ServerThread]:
    config = ServeConfig(
        store_path=tmp_path_factory.mktemp("check") / "study.db",
        model=CompensationModel.from_friction(k=0.12),
        backend=SimulatedBackend(time_scale=4.0),
        port=0,
        token=TOKEN,
        protocol=SHORT_PROTOCOL,
    )
    with ServerThread(config) as running:
        yield running


@pytest.fixture(scope="module")
def browser() -> Iterator[Windows]:
    with chromium(sync_api) as windows:
        yield windows


def live_console(browser: Windows, url: str, viewport: dict[str, int] | None = None):
    console = browser.new_page(viewport)
    console.goto(f"{url}/console#token={TOKEN}")
    console.wait_for_function("() => document.getElementById('connection').textContent === 'live'")
    console.wait_for_function("() => document.getElementById('condition').options.length === 4")
    return console


def start_from_form(console, participant: str, speed: str, repetitions: int) -> None:
    console.fill("#participant", participant)
    console.select_option("#condition", "support_25")
    console.select_option("#speed", speed)
    console.fill("#repetitions", str(repetitions))
    console.click("#start")
    console.wait_for_function("() => document.getElementById('trial-state').textContent === 'running'")


def text_of(page, element: str) -> str:
    return str(page.inner_text(f"#{element}"))


def test_a_stop_that_fails_on_the_network_is_said_and_retried_and_the_display_says_stopped(server, browser):
    display = browser.new_page()
    display.goto(f"{server.url}/display")
    display.wait_for_function("() => bowdenDisplay.connected()")
    console = live_console(browser, server.url)
    # 30 repetitions (the form's most; 38 s at this time scale), stopped by the test long before: a
    # loaded host's slow browser must not let the trial end by itself first.
    start_from_form(console, "P41", "V1", 30)
    display.wait_for_function("() => bowdenDisplay.running()")
    console.route("**/api/trial/stop", lambda route: route.abort())
    console.click("#stop")
    console.wait_for_function(
        "() => document.getElementById('stop-message').textContent.includes('did not reach')"
    )
    assert console.evaluate("bowdenConsole.stopRetrying()") and server.web.manager.running
    assert console.is_enabled("#stop")  # the stop path stays open
    console.unroute("**/api/trial/stop")  # the network is back: the retry gets through by itself
    console.wait_for_function(
        "() => document.getElementById('stop-message').textContent.startsWith('Stop requested')"
    )
    display.wait_for_function("() => !bowdenDisplay.running()")
    assert display.evaluate("bowdenDisplay.headline()") == "Stopped — rest"  # not "Done: 30 of 30"
    console.wait_for_function("() => document.getElementById('h-state').textContent === 'safe (ended)'")
    assert "stopped before its end: operator stop (console)" in text_of(console, "last-result")
    display.context.close()
    console.context.close()


def test_a_console_reloaded_mid_trial_shows_that_trial_and_escape_stops_it(server, browser):
    console = live_console(browser, server.url)
    start_from_form(console, "P42", "V1", 30)  # stopped long before its end, as above
    console.reload()  # the token stays in this tab's session storage
    console.wait_for_function("() => document.getElementById('trial-state').textContent === 'running'")
    assert console.input_value("#participant") == "P42" and console.input_value("#speed") == "V1"
    assert console.input_value("#repetitions") == "30" and console.input_value("#condition") == "support_25"
    running = text_of(console, "last-result")
    assert re.match(r"Trial \d+ running: P42, support_25, V1, 30 repetitions", running)
    console.keyboard.press("Escape")
    console.wait_for_function("() => document.getElementById('h-state').textContent === 'safe (ended)'")
    assert "operator stop (console)" in text_of(console, "last-result")
    assert not server.web.manager.running
    console.context.close()


def test_after_a_restart_a_console_with_the_old_token_can_paste_the_new_one(server, browser):
    console = browser.new_page()
    console.goto(f"{server.url}/console#token=the-token-of-the-server-before-its-restart")
    console.wait_for_function("() => document.getElementById('connection').textContent === 'token refused'")
    assert console.is_visible("#token")
    console.fill("#token", TOKEN)
    console.press("#token", "Enter")
    console.wait_for_function("() => document.getElementById('connection').textContent === 'live'")
    assert not console.is_visible("#token")
    console.context.close()


def test_a_refusal_of_the_old_token_arriving_after_the_paste_does_not_refuse_the_new_one(server, browser):
    # The race the restart test met on a busy host: the operator pastes the new token while the server's
    # refusal (close code 1008) of the socket that sent the old one is still on its way. Here the route
    # answers the page's own close of that socket with the server's 1008, so the refusal arrives after
    # the paste every time; it must not be taken for a refusal of the new token.
    console = browser.new_page()
    sockets, sent = [], []

    def route(ws) -> None:
        sockets.append(ws)
        upstream = ws.connect_to_server()
        if len(sockets) == 1:  # the old token's socket: the server's verdict is held back
            ws.on_message(lambda message: (sent.append(message), upstream.send(message)))
            upstream.on_close(lambda code, reason: None)
            ws.on_close(lambda code, reason: ws.close(code=1008, reason="wrong session token"))

    def wait_until(condition) -> None:
        for _ in range(400):  # 20 s
            if condition():
                return
            console.wait_for_timeout(50)
        raise AssertionError("the console never got there")

    console.route_web_socket("**/ws/console", route)
    console.goto(f"{server.url}/console#token=the-token-of-the-server-before-its-restart")
    console.wait_for_selector("#token", state="visible")  # refused over HTTP
    wait_until(lambda: bool(sent))  # and the old token's socket is open, its refusal held back
    console.fill("#token", TOKEN)
    console.press("#token", "Enter")
    wait_until(lambda: len(sockets) == 2)  # a refusal taken for the new token's never reconnects
    console.wait_for_function("() => document.getElementById('connection').textContent === 'live'")
    assert not console.is_visible("#token")
    console.context.close()


def test_a_portrait_tablet_reads_well_and_meets_the_contrast_and_target_sizes(server, browser):
    display = browser.new_page(TABLET_PORTRAIT)
    display.goto(f"{server.url}/display")
    display.wait_for_function("() => bowdenDisplay.connected()")
    console = live_console(browser, server.url, TABLET_PORTRAIT)
    # Four repetitions (under 10 s): a trial short enough that no backlog of a loaded host's recorder
    # (its bound is 10 s of rows) can stop it, so the end state below does not depend on the load.
    start_from_form(console, "P43", "V3", 4)
    # The disabled Start button stays readable (WCAG AA 4.5:1); the three plots have names.
    start = console.eval_on_selector(
        "#start", "b => [getComputedStyle(b).color, getComputedStyle(b).backgroundColor]"
    )
    assert contrast(*start) >= 4.5
    for name in ("Tension plot", "Motor torque plot", "Elevation plot"):
        assert console.get_by_role("img", name=re.compile(name)).count() == 1
    # STOP's focus ring: dark against the page, light against the red button (3:1 each).
    console.focus("a.nav[href='/display']")
    console.keyboard.press("Tab")  # by keyboard, as the ring is for keyboard users (:focus-visible)
    assert console.evaluate("document.activeElement.id") == "stop"
    ring = console.eval_on_selector("#stop", """b => { const s = getComputedStyle(b);
        return [s.outlineColor, s.outlineWidth, s.boxShadow, s.backgroundColor,
                getComputedStyle(document.body).backgroundColor]; }""")
    outline, width, shadow, button, page = ring
    assert float(width.removesuffix("px")) >= 2.0
    assert contrast(outline, page) >= 3.0
    assert contrast(re.match(r"rgba?\([^)]*\)", shadow).group(0), button) >= 3.0
    screenshot(console, "console-portrait.png", full_page=True)

    display.wait_for_function("() => bowdenDisplay.running() && bowdenDisplay.lastT() > 2.0")
    # No trace over the grid labels: they are drawn last, on the page colour.
    covered = display.evaluate(
        """([ref, meas]) => {
             const ctx = document.getElementById('display').getContext('2d');
             const near = (p, c) =>
               Math.abs(p[0] - c[0]) + Math.abs(p[1] - c[1]) + Math.abs(p[2] - c[2]) < 60;
             return bowdenDisplay.labelBoxes().filter((b) => {
               const data = ctx.getImageData(
                 Math.ceil(b.x), Math.ceil(b.y), Math.floor(b.w) - 1, Math.floor(b.h) - 1).data;
               for (let i = 0; i < data.length; i += 4) {
                 const p = [data[i], data[i + 1], data[i + 2]];
                 if (near(p, ref) || near(p, meas)) { return true; }
               }
               return false;
             }).map((b) => b.deg);
           }""",
        [REFERENCE_RGB, MEASURED_RGB],
    )
    assert covered == []
    screenshot(display, "display-portrait.png")
    display.wait_for_function("() => !bowdenDisplay.running()", timeout=60_000)
    assert display.evaluate("bowdenDisplay.headline()") == "Done: 4 of 4 — rest"
    width = display.evaluate("bowdenDisplay.headlineWidth()")
    assert width["text"] <= 0.95 * width["canvas"]

    # Questionnaire choices are touch targets of at least 44 × 44 px.
    page = browser.new_page(TABLET_PORTRAIT)
    page.goto(f"{server.url}/questionnaire#token={TOKEN}")
    page.wait_for_function("() => document.querySelectorAll('input[type=radio]').length === 169")
    sizes = page.evaluate("""() => Array.from(document.querySelectorAll('input[type=radio]')).map((input) => {
        const r = document.querySelector(`label[for='${input.id}']`).getBoundingClientRect();
        const i = input.getBoundingClientRect();
        return [Math.max(r.width, i.width), Math.max(r.height, i.height)]; })""")
    assert min(w for w, _ in sizes) >= 44 and min(h for _, h in sizes) >= 44
    screenshot(page, "questionnaire-portrait.png", full_page=True)
    for window in (display, console, page):
        window.context.close()
