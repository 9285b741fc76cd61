"""The trigger line: a real command on this machine, and the GPIO variant without a GPIO chip."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import pytest

from bowden.errors import HardwareError, ParameterError
from bowden.hardware.trigger import CommandTrigger, GpioTrigger, open_trigger

LOGGER = Path(__file__).parents[1] / "runtime" / "trigger_log.py"


def test_the_command_trigger_runs_its_program_with_the_level(tmp_path: Path) -> None:
    log = tmp_path / "levels.txt"
    line = open_trigger(f"command:{sys.executable} {LOGGER} {log} {{level}}")
    assert isinstance(line, CommandTrigger)
    high = line.set(True)
    low = line.set(False)
    line.close()
    written = [entry.split() for entry in log.read_text().splitlines()]
    assert [level for level, _ in written] == ["1", "0"]
    for (before, after), (_, stamp) in zip((high, low), written, strict=True):
        assert before <= float(stamp) <= after <= time.monotonic()


def test_a_failing_or_missing_command_is_a_hardware_error(tmp_path: Path) -> None:
    with pytest.raises(HardwareError, match="exited with 1: no line"):
        CommandTrigger(f"{sys.executable} -c \"import sys; sys.exit('no line') if '{{level}}' else 0\"").set(
            True
        )
    with pytest.raises(HardwareError, match="could not run"):
        CommandTrigger("/nonexistent/gpio-tool {level}").set(True)


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ("command:", "the trigger command is empty"),
        ("command:gpioset gpiochip1 28=1", "has no {level}"),
        ("gpio:28", "expected gpio:CHIP:LINE"),
        ("serial:/dev/ttyUSB0", "expected gpio:CHIP:LINE or command:"),
    ],
)
def test_bad_trigger_specs_are_refused(spec: str, message: str) -> None:
    with pytest.raises(ParameterError, match=message):
        open_trigger(spec)


def test_a_gpio_chip_that_is_not_there_is_named(tmp_path: Path) -> None:
    pytest.importorskip("gpiod")
    chip = tmp_path / "gpiochip9"
    with pytest.raises(HardwareError, match=f"no GPIO chip {chip}"):
        GpioTrigger(str(chip), 28)
    # A file that is not a GPIO character device is refused by the kernel interface, not a crash.
    chip.write_bytes(b"")
    with pytest.raises(HardwareError, match="cannot drive GPIO"):
        open_trigger(f"gpio:{chip}:28")
