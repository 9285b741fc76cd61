"""A digital trigger line for amplifiers that record a trigger input (TMSi SAGA, Delsys, g.tec...).

``bowden run --trigger SPEC`` raises the line when a trial starts and lowers it when it ends; the
amplifier records the pulse beside the sEMG and ``bowden emg import`` finds each trial from it. Two
ways to drive a line:

``gpio:CHIP:LINE``
    a Linux GPIO character device through the ``gpiod`` bindings (the ``gpio`` extra). On a
    BeagleBone Black, header pin P9_12 is GPIO1_28: ``gpio:/dev/gpiochip1:28`` (check with
    ``gpioinfo``; a 3.3 V output, so put an opto-isolator or the amplifier's trigger adapter between).
``command:TEMPLATE``
    any program, run without a shell, with ``{level}`` replaced by 1 or 0, e.g.
    ``command:gpioset -c gpiochip1 28={level}`` or a script that writes to a USB-TTL box.

:meth:`TriggerLine.set` returns the host times (``time.monotonic``) just before and just after the
change: the edge happened in between. A GPIO write takes microseconds; a command takes as long as the
program does (milliseconds), and that spread is what the import's residuals will show.
"""

from __future__ import annotations

import shlex
import subprocess
import time
from typing import Any, Protocol

from bowden.errors import HardwareError, MissingExtraError, ParameterError


class TriggerLine(Protocol):
    """A digital output: ``set(True)`` high, ``set(False)`` low; returns (before, after) host times."""

    description: str

    def set(self, high: bool) -> tuple[float, float]: ...

    def close(self) -> None: ...


class CommandTrigger:
    """A line driven by running a program (``{level}`` in its arguments becomes 1 or 0)."""

    def __init__(self, template: str, *, timeout_s: float = 2.0) -> None:
        arguments = shlex.split(template)
        if not arguments:
            raise ParameterError("the trigger command is empty (command:PROGRAM ARGS with {level})")
        if not any("{level}" in argument for argument in arguments):
            raise ParameterError(f"the trigger command {template!r} has no {{level}} to set the line with")
        self.arguments = arguments
        self.timeout_s = timeout_s
        self.description = f"command {template!r}"

    def set(self, high: bool) -> tuple[float, float]:
        level = "1" if high else "0"
        command = [argument.replace("{level}", level) for argument in self.arguments]
        before = time.monotonic()
        try:
            done = subprocess.run(command, capture_output=True, timeout=self.timeout_s, check=False)
        except (OSError, subprocess.TimeoutExpired) as error:
            raise HardwareError(f"trigger {self.description} could not run: {error}") from None
        after = time.monotonic()
        if done.returncode != 0:
            said = done.stderr.decode(errors="replace").strip().splitlines()
            raise HardwareError(
                f"trigger {self.description} exited with {done.returncode}"
                + (f": {said[-1]}" if said else "")
            )
        return before, after

    def close(self) -> None:
        """Nothing is held open between commands."""


class GpioTrigger:
    """A GPIO line of a character device (``/dev/gpiochipN``), held as an output while open."""

    def __init__(self, chip: str, line: int | str, *, consumer: str = "bowden-trigger") -> None:
        try:
            import gpiod
            from gpiod.line import Direction, Value
        except ImportError:
            raise MissingExtraError(
                "the GPIO trigger needs the gpio extra (gpiod missing): pip install 'bowden[gpio]'"
            ) from None
        self._values = {True: Value.ACTIVE, False: Value.INACTIVE}
        self.line = line
        self.description = f"GPIO {chip} line {line}"
        try:
            settings = gpiod.LineSettings(direction=Direction.OUTPUT, output_value=Value.INACTIVE)
            self._request: Any = gpiod.request_lines(chip, consumer=consumer, config={line: settings})
        except FileNotFoundError:
            raise HardwareError(
                f"no GPIO chip {chip}: this machine has no such device (list them with gpiodetect)"
            ) from None
        except (OSError, ValueError) as error:
            raise HardwareError(f"cannot drive {self.description}: {error}") from None

    def set(self, high: bool) -> tuple[float, float]:
        before = time.monotonic()
        try:
            self._request.set_value(self.line, self._values[high])
        except (OSError, ValueError) as error:
            raise HardwareError(f"cannot set {self.description}: {error}") from None
        return before, time.monotonic()

    def close(self) -> None:
        self._request.release()


def open_trigger(spec: str) -> TriggerLine:
    """A trigger line from ``gpio:CHIP:LINE`` or ``command:TEMPLATE`` (see the module docstring)."""
    kind, _, rest = spec.partition(":")
    if kind == "command":
        return CommandTrigger(rest)
    if kind == "gpio":
        chip, _, line = rest.rpartition(":")
        if not chip or not line:
            raise ParameterError(f"--trigger {spec!r}: expected gpio:CHIP:LINE, e.g. gpio:/dev/gpiochip1:28")
        return GpioTrigger(chip, int(line) if line.isdigit() else line)
    raise ParameterError(f"--trigger {spec!r}: expected gpio:CHIP:LINE or command:PROGRAM ... {{level}}")
