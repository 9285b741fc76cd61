"""The slack take-up before a trial (``LoopConfig.slack``), on the simulated suit behind its wire
peers: the motor reels in slowly in MIT velocity mode, watched like every cycle, until the cable's
pull reaches the pretension; then the controller assists. No tension in time is a safe stop."""

from __future__ import annotations

import math

import pytest

from bowden.control import Fault
from bowden.errors import ParameterError
from bowden.hardware.ak60_codec import ENTER_MOTOR_MODE, EXIT_MOTOR_MODE, unpack_command
from bowden.runtime import ControlLoop, LoopConfig
from bowden.runtime.clock import MonotonicClock
from bowden.runtime.realtime import RealtimeConfig
from bowden.runtime.safety import SafetyConfig
from bowden.runtime.slack import SlackTakeUp
from bowden.sim.arm import PrescribedArm

# The simulated devices are threads of this (perhaps busy) host, and these tests time none of the
# watchdogs: a starved motor peer ("no valid reply to the last 5 commands", 42 ms, beside two busy
# processes on 2026-11-28) is the host. A device that stays silent is still found.
ON_SHARED_HOST = SafetyConfig(imu_max_age_s=0.25, motor_max_silence_s=0.25, host_stall_max_s=1.0)


def loop(rig, controller, slack: SlackTakeUp, duration_s: float) -> ControlLoop:
    return ControlLoop(controller=controller, motor=rig.motor, elevation_sensor=rig.imu,
                       clock=MonotonicClock(),
                       config=LoopConfig(rate_hz=500.0, duration_s=duration_s, slack=slack,
                                         safety=ON_SHARED_HOST),
                       tension_sensor=rig.load_cell, realtime=RealtimeConfig())  # as bowden run's


def test_reels_in_to_the_pretension_then_assists(rig, controller):
    rig.suit.arm = PrescribedArm.hold(rig.suit.arm.initial_elevation_rad())  # standing still, arm down
    rig.plant.start()
    slack = SlackTakeUp(pretension_n=8.0)  # the simulated suit starts at 5 N
    report = loop(rig, controller, slack, duration_s=1.5).run()
    assert report.fault == Fault.NONE, report.reason
    assert 0.0 < report.slack_take_up_s < 1.0
    commands = [unpack_command(bytes(m.data), rig.motor.config.limits) for m in rig.frames()
                if m.arbitration_id == rig.motor.config.motor_id and len(m.data) == 8
                and bytes(m.data) not in (ENTER_MOTOR_MODE, EXIT_MOTOR_MODE)]
    reeling = [c for c in commands if c.velocity_rad_s > 0.25]  # a zero packs to ±0.01 rad/s
    # Reeling in: MIT velocity mode, kp 0, kd and v as configured (to the codec's resolution)...
    assert len(reeling) >= 5
    for command in reeling:
        assert command.kp == 0.0
        assert command.kd == pytest.approx(slack.kd_nms_rad, abs=0.01)
        assert command.velocity_rad_s == pytest.approx(slack.velocity_rad_s, abs=0.05)
    # ...then the controller's torque commands, which never go back to reeling.
    first_torque = next(i for i, c in enumerate(commands) if c.velocity_rad_s < 0.25)
    assert first_torque == len(reeling)
    assert all(c.velocity_rad_s < 0.25 and c.kd == 0.0 for c in commands[first_torque:])
    assert max(c.torque_nm for c in commands[first_torque:]) > 0.5


def test_a_cable_that_never_tightens_is_a_safe_stop(rig, controller):
    rig.plant.start()
    rig.adc.override_tension_n(0.0)  # the load cell sees nothing: the cable hangs loose
    report = loop(rig, controller, SlackTakeUp(timeout_s=0.3), duration_s=5.0).run()
    assert report.fault == Fault.SLACK_NOT_TAKEN_UP
    assert "is it attached?" in report.reason
    assert math.isnan(report.slack_take_up_s)
    assert report.motor_disabled and rig.peer_leaves_motor_mode()
    assert report.stop_time_s == pytest.approx(0.3, abs=0.05)


def test_an_unreachable_pretension_is_refused():
    with pytest.raises(ParameterError, match="cannot be reached"):
        SlackTakeUp(pretension_n=10.0, kd_nms_rad=1.0, velocity_rad_s=0.5, pulley_radius_m=0.035)


def test_without_a_load_cell_the_pull_is_the_motors_torque_over_the_pulley():
    slack = SlackTakeUp(pulley_radius_m=0.04)
    assert slack.pull_n(math.nan, 0.2) == pytest.approx(5.0)
    assert slack.pull_n(7.0, 0.2) == 7.0


def test_bowden_run_says_when_the_slack_was_taken_up(capsys):
    from bowden.cli import main

    # The host-stall bound out of the way (its own tests are in tests/runtime/test_host_stall.py): a
    # 157 ms stall stopped this run once in an idle suite with three workers, before its message.
    code = main(["run", "--backend", "sim", "--duration", "1", "--slack-take-up", "on", "--rt-priority", "0",
                 "--host-stall-ms", "1000"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "slack take-up: in " in out


def test_serve_starts_its_trials_the_same_way(tmp_path):
    pytest.importorskip("starlette")
    from bowden.cli import build_parser
    from bowden.cli.serve import serve_config

    def config(*extra: str):
        args = build_parser().parse_args(["serve", "--store", str(tmp_path / "s.db"), *extra])
        return serve_config(args)

    assert config().slack is None  # the simulated suit starts taut
    slack = config("--slack-take-up", "on", "--slack-timeout", "4").slack
    assert slack is not None and slack.timeout_s == 4.0
    assert slack.pulley_radius_m == pytest.approx(config().model.pulley_radius_m)
