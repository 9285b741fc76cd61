"""What a trial's metadata records of the suit's hardware: which actuator and which IMU it ran on.

``bowden run`` and ``bowden serve`` (either backend) write the same three keys into every trial's
metadata, so the store can tell a trial on an AK70-10 with an LSL IMU from one on the paper's AK60-6
with its NGIMU, and the firmware variant whose field ranges the driver used.
"""

from __future__ import annotations

from bowden.hardware.lsl_imu import parse_imu
from bowden.hardware.motors import motor_model


def device_record(motor: str, firmware: str | None, imu: str) -> dict[str, str]:
    """The trial metadata of the hardware: ``motor_model``, ``motor_firmware``, ``imu``.

    Parameters
    ----------
    motor, firmware
        ``--motor`` and ``--firmware`` (None: the model's default variant, recorded by its name).
    imu
        ``--imu``: ``ngimu`` or ``lsl:STREAM_NAME`` (recorded with the name stripped as it is read).

    Raises
    ------
    ParameterError
        Naming ``--motor``, ``--firmware`` or ``--imu`` when one is not known.
    """
    model = motor_model(motor)
    model.limits(firmware)
    stream = parse_imu(imu)
    return {
        "motor_model": model.name,
        "motor_firmware": firmware if firmware is not None else model.default_firmware,
        "imu": "ngimu" if stream is None else f"lsl:{stream}",
    }
