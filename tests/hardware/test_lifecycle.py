"""The lifecycle helpers of the drivers and peers: a stoppable, restartable thread; start/close in `with`."""

from __future__ import annotations

import threading
from typing import Self

import pytest

from bowden.hardware.lifecycle import StartedInWith, StoppableThread


def test_stoppable_thread_runs_until_stopped_and_can_run_again() -> None:
    lapped = threading.Event()

    def target() -> None:
        while not worker.stop_requested.wait(0.005):
            lapped.set()

    worker = StoppableThread(target, "test-worker")
    assert not worker.running
    worker.start()
    worker.start()  # a second start while running is a no-op
    assert lapped.wait(2.0) and worker.running
    assert [t.name for t in threading.enumerate()].count("test-worker") == 1
    worker.stop()
    assert not worker.running and "test-worker" not in [t.name for t in threading.enumerate()]
    lapped.clear()
    worker.start()  # the stop flag is cleared again, so the target loops instead of returning at once
    assert lapped.wait(2.0)
    worker.stop()
    assert "test-worker" not in [t.name for t in threading.enumerate()]


def test_with_starts_and_closes_even_when_the_body_raises() -> None:
    calls = []

    class Device(StartedInWith):
        def start(self) -> Self:
            calls.append("start")
            return self

        def close(self) -> None:
            calls.append("close")

    with Device() as device:
        assert isinstance(device, Device) and calls == ["start"]
    with pytest.raises(RuntimeError), Device():
        raise RuntimeError("boom")
    assert calls == ["start", "close", "start", "close"]
