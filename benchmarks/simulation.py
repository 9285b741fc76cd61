"""Simulation speed and the simulated study's tension tracking, measured in one run.

    .venv/bin/python benchmarks/simulation.py [--participants 17] [--table]
        [--cohort-seed N] [--sheath-kinetic k] [--sheath-viscous N·s/m] [--motor-coulomb Nm]
        [--motor-viscous Nm·s/rad] [--rotor-inertia kg·m²] [--wearer-friction-sd log-SD]

Prints simulated seconds per wall second for the plant alone, for the SimulatedSuit driven by a
Python control loop (as the runtime does) and for the batch study, and the wall time of the whole
cohort protocol (17 participants x 4 conditions x 3 speeds x 10 repetitions; target <= 60 s, goal
<= 20 s). It also prints the lines identified on the simulated bench: slopes against the plant's
quasi-static slopes R(1 ± k)/(1 ∓ k)/c and R² in both definitions. With ``--table`` it prints the
tension RMSE table of docs/simulation.md, with the controller identified on the simulated bench.
The suit options replace one default each, for the sensitivity runs of docs/simulation.md.
"""

from __future__ import annotations

import argparse
import math
import time
from collections import defaultdict
from dataclasses import replace

import numpy as np

from bowden import contracts as c
from bowden.control import build_controller
from bowden.identify import TransmissionIdentifier
from bowden.model.transmission import slopes_from_friction
from bowden.sim import PrescribedArm, SimulatedSuit, generate_cohort, run_bench, simulate_cohort
from bowden.sim import _kernels as k
from bowden.sim.parameters import ArmParameters, SuitParameters
from bowden.sim.participants import WEARER_FRICTION_LOG_SD
from bowden.sim.plant import Plant
from bowden.sim.results import TRUE_TENSION, phase_masks, rmse


def plant_rate(parameters: SuitParameters) -> float:
    plant = Plant(parameters, ArmParameters(), elevation_rad=1.0, tension_n=10.0)
    n = 400_000  # 100 s
    t = np.arange(n) * plant.substep_s
    args = dict(motor_mode=k.MOTOR_TORQUE, command=np.array([0.4, 0, 0, 0, 0.0]), arm_mode=k.ARM_PRESCRIBED,
                arm_a=1.0 + 0.5 * np.sin(t), arm_b=0.5 * np.cos(t))
    plant.integrate(100, **{**args, "arm_a": args["arm_a"][:100], "arm_b": args["arm_b"][:100]})  # compile
    start = time.perf_counter()
    plant.integrate(n, **args)
    return n * plant.substep_s / (time.perf_counter() - start)


def loop_rate(model: object, parameters: SuitParameters) -> float:
    subject = generate_cohort(0)[0].subject
    controller = build_controller(model=model, support=0.5, subject=subject)  # type: ignore[arg-type]
    suit = SimulatedSuit(parameters, arm=PrescribedArm.hold(1.0), initial_tension_n=10.0)
    suit.motor.enable()
    t, duration = 0.0, 10.0
    start = time.perf_counter()
    while t < duration:
        sample = suit.elevation_sensor.read()
        torque = 0.0
        if sample is not None:
            torque = controller.step(t, sample.elevation_rad, sample.elevation_velocity_rad_s).torque_nm
        suit.motor.command_torque(torque)
        t += 0.002
        suit.clock.sleep_until(t)
    return duration / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--participants", type=int, default=17)
    parser.add_argument("--table", action="store_true", help="print the tension RMSE table")
    parser.add_argument("--cohort-seed", type=int, default=0, help="seed of the cohort and the study")
    parser.add_argument("--sheath-kinetic", type=float, help="SheathParameters.kinetic_coefficient")
    parser.add_argument("--sheath-viscous", type=float, help="SheathParameters.viscous_coefficient_ns_m")
    parser.add_argument("--motor-coulomb", type=float, help="MotorParameters.coulomb_friction_nm")
    parser.add_argument("--wearer-friction-sd", type=float, default=WEARER_FRICTION_LOG_SD,
                        help="generate_cohort's wearer_friction_log_sd")
    parser.add_argument("--motor-viscous", type=float, help="MotorParameters.viscous_friction_nms_rad")
    parser.add_argument("--rotor-inertia", type=float, help="MotorParameters.rotor_inertia_kgm2")
    args = parser.parse_args()
    suit = SuitParameters()
    if args.sheath_kinetic is not None:
        suit = replace(suit, sheath=replace(suit.sheath, kinetic_coefficient=args.sheath_kinetic))
    if args.motor_coulomb is not None:
        suit = replace(suit, motor=replace(suit.motor, coulomb_friction_nm=args.motor_coulomb))
    if args.sheath_viscous is not None:
        suit = replace(suit, sheath=replace(suit.sheath, viscous_coefficient_ns_m=args.sheath_viscous))
    if args.motor_viscous is not None:
        suit = replace(suit, motor=replace(suit.motor, viscous_friction_nms_rad=args.motor_viscous))
    if args.rotor_inertia is not None:
        suit = replace(suit, motor=replace(suit.motor, rotor_inertia_kgm2=args.rotor_inertia))

    start = time.perf_counter()
    bench = run_bench(suit, seed=0)
    bench_wall = time.perf_counter() - start
    model = TransmissionIdentifier(pulley_radius_m=suit.motor.spool_radius_m).fit(bench).model_
    print(f"bench: {bench['time_s'].iloc[-1]:.0f} s simulated in {bench_wall:.1f} s wall "
          f"({bench['time_s'].iloc[-1] / bench_wall:.0f} simulated s per wall s)")
    raising, lowering = slopes_from_friction(suit.sheath.kinetic_coefficient, suit.motor.spool_radius_m)
    ratio = suit.motor.torque_constant_ratio
    for name, line, fit, quasi_static in (
        ("raising", model.raising, model.raising_fit, raising / ratio),
        ("lowering", model.lowering, model.lowering_fit, lowering / ratio),
    ):
        assert fit is not None
        deviation = 100 * (line.slope_m / quasi_static - 1)
        print(f"identified {name}: slope {line.slope_m:.5f} m ({deviation:+.2f} % "
              f"vs quasi-static {quasi_static:.5f}), intercept {line.intercept_nm:+.4f} Nm, "
              f"R² robust (fitlm) {fit.r_squared_robust:.4f}, OLS {fit.r_squared_ols:.4f}")
    print(f"plant alone: {plant_rate(suit):.0f} simulated s per wall s")
    print(f"SimulatedSuit + Controller.step in a Python loop at 500 Hz: {loop_rate(model, suit):.1f} "
          "simulated s per wall s")

    cohort = generate_cohort(
        args.cohort_seed, n_participants=args.participants, wearer_friction_log_sd=args.wearer_friction_sd
    )
    start = time.perf_counter()
    result = simulate_cohort(cohort, model=model, suit=suit, seed=args.cohort_seed)
    wall = time.perf_counter() - start
    simulated = sum(t.duration_s for t in result.trials)
    print(f"whole cohort ({len(cohort)} participants, {len(result.trials)} trials, "
          f"{simulated:.0f} s simulated, questionnaires included): {wall:.1f} s wall, "
          f"{simulated / wall:.0f} simulated s per wall s (target <= 60 s, goal <= 20 s)")
    if args.table:
        print_table(result)


def print_table(result: object) -> None:
    cells: dict[tuple[str, str, str], list[float]] = defaultdict(list)
    peaks: dict[tuple[str, str], list[tuple[float, float]]] = defaultdict(list)
    for trial in result.trials:  # type: ignore[attr-defined]
        if not trial.wears_suit:
            continue
        desired, true = trial[c.TRIAL_DESIRED_TENSION], trial[TRUE_TENSION]
        for phase, mask in phase_masks(trial).items():
            cells[(trial.condition, trial.speed, phase)].append(rmse(true[mask], desired[mask]))
        frac, rep = trial.cycle_fraction(), trial.repetition_index()
        err = 100.0 * (true - desired) / desired
        for r in range(1, trial.repetitions):
            m = (rep == r) & (frac >= 0.5)
            i = int(np.argmax(err[m]))
            peaks[(trial.condition, trial.speed)].append((float(err[m][i]), 100.0 * float(frac[m][i])))
    print("\n| Tension RMSE (N) | V1 entire | raise | lower | V2 entire | raise | lower "
          "| V3 entire | raise | lower |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for condition in (c.CONDITION_PRETENSION, c.CONDITION_SUPPORT_25, c.CONDITION_SUPPORT_50):
        row = [
            f"{np.mean(cells[(condition, s, p)]):.2f}"
            for s in c.SPEEDS
            for p in ("entire", "raising", "lowering")
        ]
        print(f"| {c.CONDITION_LABELS[condition]} | " + " | ".join(row) + " |")
    entire = np.array([
        [np.mean(cells[(condition, s, "entire")]) for s in c.SPEEDS]
        for condition in (c.CONDITION_PRETENSION, c.CONDITION_SUPPORT_25, c.CONDITION_SUPPORT_50)
    ])
    with_speed, with_support = np.all(np.diff(entire, axis=1) > 0), np.all(np.diff(entire, axis=0) > 0)
    print(f"\nentire-cycle RMSE grows with speed in every condition: {bool(with_speed)}; "
          f"with support at every speed: {bool(with_support)}")
    print("\n| Peak lowering error | V1 | V2 | V3 |")
    print("|---|---|---|---|")
    for condition in (c.CONDITION_PRETENSION, c.CONDITION_SUPPORT_25, c.CONDITION_SUPPORT_50):
        row = []
        for s in c.SPEEDS:
            values = np.array(peaks[(condition, s)])
            row.append(f"{values[:, 0].mean():.0f} % at {values[:, 1].mean():.0f} %")
        print(f"| {c.CONDITION_LABELS[condition]} | " + " | ".join(row) + " |")
    print("\n| Elevation RMSE (deg) | V1 | V2 | V3 |")
    print("|---|---|---|---|")
    for condition in c.CONDITIONS:
        row = []
        for s in c.SPEEDS:
            values = []
            for trial in result.trials:  # type: ignore[attr-defined]
                if trial.condition == condition and trial.speed == s:
                    m = phase_masks(trial)["entire"]
                    error = rmse(trial[c.TRIAL_ELEVATION][m], trial[c.TRIAL_REFERENCE_ELEVATION][m])
                    values.append(math.degrees(error))
            row.append(f"{np.mean(values):.1f}")
        print(f"| {c.CONDITION_LABELS[condition]} | " + " | ".join(row) + " |")


if __name__ == "__main__":
    main()
