"""A whole (shortened) session run as an operator would, in Chromium: register, follow the plan through
the four conditions with the questionnaires between them, restart the server mid-session and resume
with the new token, redo one trial; then ``bowden analyze`` reports it with the registered
anthropometrics and the plan's condition order. The screenshots are those of docs/web.md."""

from __future__ import annotations

import socket
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from bowden.cli import main
from bowden.contracts import FATIGUE_SITES, NORDIC_SITES
from bowden.model import CompensationModel
from bowden.store.schema import STORE_FILE_NAME
from bowden.web.server import ServeConfig, ServerThread
from bowden.web.suits import SimulatedBackend

from .browser import CHROMIUM, Windows, chromium, screenshot
from .conftest import SHORT_PROTOCOL

sync_api = pytest.importorskip("playwright.sync_api")
pytestmark = pytest.mark.skipif(not CHROMIUM.exists(), reason="Debian's chromium is not installed")
FIRST_TOKEN = "first-session-token-0123456789"
SECOND_TOKEN = "after-the-restart-token-98765"


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


@contextmanager
def server(store: Path, port: int, token: str) -> Iterator[ServerThread]:
    config = ServeConfig(store_path=store, model=CompensationModel.from_friction(k=0.12),
                         backend=SimulatedBackend(time_scale=4.0), port=port, token=token,
                         protocol=SHORT_PROTOCOL)
    with ServerThread(config) as running:
        yield running


def wait_text(page, element: str, text: str) -> None:
    page.wait_for_function(
        "([id, text]) => document.getElementById(id).textContent.includes(text)", arg=[element, text]
    )


def run_next(console, position: int) -> None:
    """Start the plan's next trial in one action and wait until the plan has moved on."""
    wait_text(console, "next-text", f"Next: trial {position} of 4")
    console.click("#start-next")
    console.wait_for_function(
        "(p) => document.querySelector(`#plan tbody tr:nth-child(${p})`).className === 'state-done'",
        arg=position,
    )


def answer(browser: Windows, url: str, token: str, participant: str, condition: str) -> None:
    """The questionnaires after a condition, opened as the console's prompt links them."""
    page = browser.new_page()
    page.goto(f"{url}/questionnaire#token={token}&participant={participant}&condition={condition}")
    page.wait_for_function("() => document.querySelectorAll('input[type=radio]').length === 169")
    assert page.input_value("#participant") == participant and page.input_value("#condition") == condition
    for k, site in enumerate(NORDIC_SITES):
        page.locator(f"[id='nordic.{site}-{1 + k % 3}']").check()
    page.locator("[id='borg_rpe-11']").check()
    for site in FATIGUE_SITES:
        page.locator(f"[id='fatigue.{site}-2']").check()
    if condition == "no_suit":
        screenshot(page, "session-questionnaire.png", full_page=True)
    page.click("#submit")
    wait_text(page, "message", f"Stored 23 answers of {participant} after {condition}.")
    page.context.close()


def test_an_operator_runs_a_whole_session_restarts_the_server_and_analyzes_it(
    tmp_path: Path
) -> None:
    store, port = tmp_path / STORE_FILE_NAME, free_port()
    with chromium(sync_api) as browser:
        with server(store, port, FIRST_TOKEN) as first:
            url = first.url
            console = browser.new_page({"width": 1280, "height": 1000})
            console.goto(f"{url}/console#token={FIRST_TOKEN}")
            wait_text(console, "connection", "live")
            # Register once.
            console.fill("#reg-participant", "P01")
            console.fill("#reg-height", "1.64")
            console.fill("#reg-mass", "58.5")
            console.select_option("#reg-arm", "left")
            console.fill("#reg-age", "29")
            console.click("#register")
            wait_text(console, "session-message", "P01 registered.")
            # The plan, drawn from a recorded seed, stored before the first trial.
            console.fill("#reg-seed", "2026")
            console.click("#open-session")
            wait_text(console, "plan-summary", "seed 2026")
            order = first.web.desk.store.latest().order
            assert order[0] == "no_suit"
            assert console.locator("#plan tbody tr").count() == 4
            screenshot(console, "session-plan.png", full_page=True)
            # First condition; the questionnaires are prompted after it, and the break timer runs.
            run_next(console, 1)
            wait_text(console, "questionnaire-due", "Questionnaires due after “no suit”: open the")
            wait_text(console, "break-timer", "Break after “no suit”: ")
            screenshot(console, "session-questionnaire-due.png", full_page=True)
            answer(browser, url, FIRST_TOKEN, "P01", order[0])
            console.wait_for_function("() => document.getElementById('questionnaire-due').hidden")
            # Redo the first trial (the cuff slipped): the trial is kept and marked, the step runs again.
            console.fill("#decision-reason", "cuff slipped")
            console.click("#plan button[data-action='redo'][data-position='1']")
            wait_text(console, "session-message", "Trial 1 will run again.")
            run_next(console, 1)
            run_next(console, 2)
            answer(browser, url, FIRST_TOKEN, "P01", order[1])
        # The server is restarted mid-session, with a new token: the console says so and takes it.
        with server(store, port, SECOND_TOKEN):
            wait_text(console, "connection", "token refused")
            console.fill("#token", SECOND_TOKEN)
            console.press("#token", "Enter")
            wait_text(console, "connection", "live")
            wait_text(console, "next-text", "Next: trial 3 of 4")  # resumed from the store
            screenshot(console, "session-resumed.png", full_page=True)
            run_next(console, 3)
            answer(browser, url, SECOND_TOKEN, "P01", order[2])
            run_next(console, 4)
            answer(browser, url, SECOND_TOKEN, "P01", order[3])
            wait_text(console, "next-text", "The plan is complete.")
            wait_text(console, "progress", "4 of 4 trials")
            screenshot(console, "session-complete.png", full_page=True)
            console.context.close()

    assert main(["analyze", str(tmp_path), "--quiet"]) == 0
    report = (tmp_path / "report.html").read_text(encoding="utf-8")
    # The registry's anthropometrics and the plan's condition order are in the report.
    assert "Participants as registered" in report
    assert all(value in report for value in ("1.64", "58.5", "left", "29"))
    assert " → ".join(order) in report and "2026" in report
    # The redone trial is kept in the store and named, not analysed.
    assert "set aside: redone by the operator: cuff slipped" in report
