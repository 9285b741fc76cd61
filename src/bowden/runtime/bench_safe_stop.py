"""The bench's safe stop: both torques ramped to zero, then both motors out of motor mode."""

from __future__ import annotations

import contextlib

from bowden.errors import HardwareError
from bowden.runtime.bench_config import BenchDevices


def safe_stop(devices: BenchDevices, *, period_s: float, ramp_down_s: float, tdu_torque_nm: float,
              mannequin_torque_nm: float, errors: list[str]) -> float:
    """Ramp both torques to zero over ``ramp_down_s`` (from ``tdu_torque_nm`` and
    ``mannequin_torque_nm``), then leave motor mode; the clock time after. Problems leaving motor
    mode are appended to ``errors``."""
    clock, tdu, mannequin = devices.clock, devices.tdu, devices.mannequin
    ramp = ramp_down_s
    tdu_from = tdu_torque_nm
    load_from = mannequin_torque_nm
    start = clock.now()
    deadline = start
    while True:
        deadline += period_s
        # By the clock once the cycles run late (a busy host, a motor's driver slow to send), as the
        # suit's loop ramps (runtime.safety.ramp_torque_nm): counted in cycles, 30 late ones once
        # stretched a 30 ms ramp to 117 ms, and the exit frames came 152 ms after a silent motor.
        fraction = max(1.0 - (max(deadline, clock.now()) - start) / ramp, 0.0)
        for motor, torque in ((tdu, tdu_from * fraction), (mannequin, load_from * fraction)):
            with contextlib.suppress(HardwareError, OSError):  # the exit frame below is what matters
                motor.command_torque(torque)
        if fraction == 0.0:
            break
        clock.sleep_until(deadline)
    # Every exit frame goes out before any reply is waited for: a silent motor delays no other.
    sent = []
    for name, motor in (("TDU", tdu), ("mannequin motor", mannequin)):
        try:
            motor.request_exit()
            sent.append(motor)
        except (HardwareError, OSError) as error:
            errors.append(f"{name}: could not leave motor mode: {error}")
    # A motor that did not answer may not have heard its exit (a frame lost on the bus): once more.
    unconfirmed = [motor for motor in sent if not motor.await_exit()]
    for motor in unconfirmed:
        with contextlib.suppress(HardwareError, OSError):
            motor.request_exit()
    for motor in unconfirmed:
        motor.await_exit()
    return clock.now()
