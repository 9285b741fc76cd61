"""Commands sent to the motor and what came back.

The loop sends one command per cycle without waiting; the motor's newest reply serves the next
cycle. This keeps the books the motor watchdogs judge: the latest valid reply, the commands sent
since it (and when the oldest went out), failed transmissions in a row, malformed replies.
"""

from __future__ import annotations

import math

from bowden.errors import DeviceTimeoutError, HardwareError, TransmitError
from bowden.hardware.protocols import Motor, MotorState


class MotorLink:
    """One motor's command channel, as the loop's watchdogs see it.

    Attributes
    ----------
    reply
        The latest valid reply (None before the first).
    unanswered, oldest_unanswered_s
        Commands sent since the latest valid reply, and the clock time the oldest of them went out.
    timeouts
        Cycles whose command brought no new reply.
    transmit_failures, consecutive_transmit_failures, transmit_error
        Failed transmissions in all and in a row, and the latest one's message.
    """

    __slots__ = ("_malformed", "_motor", "consecutive_transmit_failures", "oldest_unanswered_s", "reply",
                 "timeouts", "transmit_error", "transmit_failures", "unanswered")

    def __init__(self, motor: Motor, first_reply: MotorState | None) -> None:
        self._motor = motor
        self.reply = first_reply
        self.unanswered = 0
        self.oldest_unanswered_s = math.nan
        self.timeouts = 0
        self.transmit_failures = self.consecutive_transmit_failures = 0
        self.transmit_error = ""
        self._malformed = False

    @property
    def malformed(self) -> bool:
        """Whether the replies since the latest valid one were malformed (for the silence message)."""
        return self._malformed or bool(getattr(self._motor, "last_malformed", None))

    def send(
        self, now: float, torque_nm: float, velocity_rad_s: float = math.nan, kd_nms_rad: float = 0.0
    ) -> None:
        """Command ``torque_nm`` at clock time ``now``, or with a finite ``velocity_rad_s`` that velocity
        in MIT mode with damping ``kd_nms_rad`` (slack take-up; the motor must have ``command_mit``)."""
        try:
            if velocity_rad_s == velocity_rad_s:
                new_reply = self._motor.command_mit(  # type: ignore[attr-defined]
                    0.0, velocity_rad_s, 0.0, kd_nms_rad
                )
            else:
                new_reply = self._motor.command_torque(torque_nm)
        except TransmitError as error:
            self.transmit_failures += 1
            self.consecutive_transmit_failures += 1
            self.transmit_error = str(error)
            return
        # Any other refusal or a timeout of a motor that waits: no new reply this cycle.
        except DeviceTimeoutError:
            new_reply = None
        except HardwareError:
            new_reply = None
            self._malformed = True
        self.consecutive_transmit_failures = 0
        if new_reply is not None:
            self.reply = new_reply
            self._malformed = False
            self.unanswered, self.oldest_unanswered_s = 1, now  # the command just sent awaits its reply
        else:
            self.timeouts += 1
            if self.unanswered == 0:
                self.oldest_unanswered_s = now
            self.unanswered += 1
