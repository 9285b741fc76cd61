"""The batch simulation's sensors read what the wire path's drivers read, bit for bit, and the store
keeps a simulated trial's readings as codes (AK60, ADS1115) or float32 (NGIMU)."""

from __future__ import annotations

import json
import struct
from typing import Any

import numpy as np
import pytest

from bowden import contracts as c
from bowden.hardware.ads1115 import (
    REG_CONFIG,
    REG_CONVERSION,
    LoadCellCalibration,
    conversion_to_volts,
    encode_config,
    register_bytes,
)
from bowden.hardware.ak60_codec import MitReply, pack_reply, unpack_reply
from bowden.sim import generate_cohort, simulate_trial
from bowden.sim.parameters import LoadCellParameters
from bowden.sim.peers import ADS1115Peer
from bowden.sim.sensor_readings import MOTOR_REPLY_LIMITS, ak60_torque, ak60_velocity, load_cell_reading
from bowden.store.sample_chunks import chunk_row, columns_from_frame

from .test_batch import MODEL, SHORT

VALUES = np.concatenate([
    np.random.default_rng(0).normal(0.0, 8.0, 2000),
    [0.0, -0.0, 15.0, -15.0, 45.0, -45.0, 1e3, -1e3],  # field ends and beyond: clamped
])


def test_motor_reply_fields_are_what_the_driver_decodes() -> None:
    torque = ak60_torque(VALUES, MOTOR_REPLY_LIMITS)
    velocity = ak60_velocity(VALUES, MOTOR_REPLY_LIMITS)
    for i, value in enumerate(VALUES):
        frame = pack_reply(MitReply(motor_id=1, position_rad=0.0, velocity_rad_s=float(value),
                                    torque_nm=float(value), temperature_c=25.0, error_code=0),
                           MOTOR_REPLY_LIMITS)
        reply = unpack_reply(frame, MOTOR_REPLY_LIMITS)
        assert torque[i] == reply.torque_nm and velocity[i] == reply.velocity_rad_s
    assert np.isnan(ak60_torque(np.array([np.nan]), MOTOR_REPLY_LIMITS)).all()


def test_load_cell_is_what_the_driver_reads_from_the_simulated_adc() -> None:
    cell = LoadCellParameters()
    now = [0.0]
    peer = ADS1115Peer(plant=None, offset_v=cell.adc_offset_v, volts_per_newton=1.0 / cell.gain_n_per_v,  # type: ignore[arg-type]
                       time_source=lambda: now[0])
    peer.write_register(REG_CONFIG, register_bytes(encode_config(mux=0, pga=1, continuous=True, data_rate=7)))
    calibration = LoadCellCalibration(offset_v=cell.adc_offset_v, gain_n_per_v=cell.gain_n_per_v)
    tensions = np.concatenate([VALUES * 10.0, [1e5, -1e5]])  # ± beyond the ADC's range: clamped codes
    readings = load_cell_reading(tensions, cell)
    for tension, reading in zip(tensions, readings, strict=True):
        peer.override_tension_n(float(tension))
        now[0] += 1.0  # one conversion later
        wire = calibration.tension_n(conversion_to_volts(peer.read_register(REG_CONVERSION, 2), 4.096))
        assert reading == wire
    assert np.isnan(load_cell_reading(np.array([np.nan]), cell)).all()


def stored_filters(columns: dict[str, Any]) -> dict[str, str]:
    blob = chunk_row(1, columns)[4]
    (length,) = struct.unpack("<I", blob[4:8])
    return {column["name"]: column["filter"] for column in json.loads(blob[8 : 8 + length])["columns"]}


@pytest.mark.parametrize("condition", [c.CONDITION_SUPPORT_50, c.CONDITION_NO_SUIT])
def test_a_simulated_trial_is_stored_as_codes_and_float32(condition: str) -> None:
    trial = simulate_trial(generate_cohort(0)[2], condition, "V2", model=MODEL, settings=SHORT, seed=4)
    frame = trial.to_pandas()
    for name in (c.TRIAL_ELEVATION, c.TRIAL_ELEVATION_VELOCITY):
        values = frame[name].to_numpy()
        assert np.array_equal(values.astype(np.float32).astype(np.float64), values)
    filters = stored_filters(columns_from_frame(frame))
    assert filters[c.TRIAL_ELEVATION] == filters[c.TRIAL_ELEVATION_VELOCITY] == "f32xor"
    suit = {c.TRIAL_MOTOR_TORQUE, c.TRIAL_MOTOR_VELOCITY, c.TRIAL_TENSION}
    if condition == c.CONDITION_NO_SUIT:
        assert all(frame[name].isna().all() for name in suit)  # nothing of the suit, stored as xor
    else:
        assert {filters[name] for name in suit} == {"grid"}
