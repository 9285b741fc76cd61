"""Time Controller.step() against a minimal inline computation of the same arithmetic.

The inline version is what a hand-written loop body would do with the constants already in local
variables: gravity torque, moment arm, support law with floor, sigmoid blend, torque clamp and rate
limit — no input checks, no object. The ratio shows what the controller's safety checks, state and
Command cost on top. Issue 2 asks for ≤ 5 µs per step and a ratio ≤ 1.5.

Run: python benchmarks/controller.py [--steps N] [--repeats R]
"""

from __future__ import annotations

import argparse
import math
import statistics
import time
from dataclasses import replace

from bowden.control import build_controller
from bowden.model import CompensationLine, CompensationModel, Subject
from bowden.model.anthropometry import STANDARD_GRAVITY_M_S2
from bowden.model.dynamic import DynamicCompensation


def make_inputs(n: int) -> list[tuple[float, float, float]]:
    """A V2 minimum-jerk-like sweep of elevation and velocity at 500 Hz."""
    out = []
    for i in range(n):
        t = i * 0.002
        phase = (t % 2.5) / 2.5
        elevation = math.radians(60.0 - 40.0 * math.cos(2 * math.pi * phase))
        velocity = math.radians(40.0) * 2 * math.pi / 2.5 * math.sin(2 * math.pi * phase)
        out.append((t, elevation, velocity))
    return out


def time_per_call(fn, inputs, repeats: int) -> float:
    """Median over repeats of the mean time per call, seconds."""
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        for t, e, v in inputs:
            fn(t, e, v)
        samples.append((time.perf_counter() - start) / len(inputs))
    return statistics.median(samples)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=20000)
    parser.add_argument("--repeats", type=int, default=15)
    args = parser.parse_args()

    model = CompensationModel(
        raising=CompensationLine(intercept_nm=0.06, slope_m=0.045),
        lowering=CompensationLine(intercept_nm=-0.05, slope_m=0.026),
    )
    subject = Subject(height_m=1.70, mass_kg=63.0, sex="female")
    ctrl = build_controller(model=model, support=0.5, subject=subject)

    # The same constants, as locals of a closure.
    ab = 0.12 * 0.18
    aabb = 0.12**2 + 0.18**2
    psi = math.radians(160.0)
    support_moment = 0.5 * STANDARD_GRAVITY_M_S2 * ctrl.arm.total_moment_kg_m
    floor, max_tension = 10.0, ctrl.limits.max_tension_n
    b_low, m_low = -0.05, 0.026
    d_b, d_m = 0.06 - -0.05, 0.045 - 0.026
    steep, mid = model.blend_steepness_s_rad, model.blend_midpoint_rad_s
    max_torque, rate = ctrl.limits.max_torque_nm, ctrl.limits.max_torque_rate_nm_s
    last_torque, last_time = 0.0, math.nan
    sin, cos, sqrt, exp = math.sin, math.cos, math.sqrt, math.exp

    def inline(t: float, e: float, v: float) -> tuple[float, float]:
        nonlocal last_torque, last_time
        alpha = psi - e
        r = ab * sin(alpha) / sqrt(aabb - 2.0 * ab * cos(alpha))
        tension = support_moment * sin(e) / r
        if tension < floor:
            tension = floor
        if tension > max_tension:
            tension = max_tension
        x = steep * (v - mid)
        if x >= 0.0:
            w = 1.0 / (1.0 + exp(-x))
        else:
            ex = exp(x)
            w = ex / (1.0 + ex)
        torque = b_low + m_low * tension + (d_b + d_m * tension) * w
        if torque > max_torque:
            torque = max_torque
        elif torque < 0.0:
            torque = 0.0
        dt = t - last_time
        if not 0.0 < dt < 0.1:
            dt = 0.002
        step = rate * dt
        if torque > last_torque + step:
            torque = last_torque + step
        elif torque < last_torque - step:
            torque = last_torque - step
        last_torque, last_time = torque, t
        return torque, tension

    inputs = make_inputs(args.steps)
    for t, e, v in inputs[:50]:  # same results, so the comparison is of equal work
        ctrl_cmd = ctrl.step(t, e, v)
        torque, _ = inline(t, e, v)
        assert math.isclose(ctrl_cmd.torque_nm, torque, rel_tol=1e-12, abs_tol=1e-15), (ctrl_cmd, torque)
    ctrl.reset()
    last_torque, last_time = 0.0, math.nan

    # The dynamic compensation (issue 17: <= 3 us per step), on the same inputs and machine.
    dynamic_model = replace(
        model,
        dynamic=DynamicCompensation(
            raising=CompensationLine(intercept_nm=0.08, slope_m=0.045),
            lowering=CompensationLine(intercept_nm=-0.07, slope_m=0.026),
            viscous_nm_s_rad=0.04,
            inertia_kg_m2=1.5e-3,
        ),
    )
    dynamic = build_controller(model=dynamic_model, support=0.5, subject=subject, compensation="dynamic")

    # Interleave them so machine load affects all alike.
    step_times, inline_times, dynamic_times = [], [], []
    for _ in range(args.repeats):
        step_times.append(time_per_call(ctrl.step, inputs, 1))
        inline_times.append(time_per_call(inline, inputs, 1))
        dynamic_times.append(time_per_call(dynamic.step, inputs, 1))
    step_s = statistics.median(step_times)
    inline_s = statistics.median(inline_times)
    dynamic_s = statistics.median(dynamic_times)
    print(f"Controller.step   median {step_s * 1e6:7.3f} us/step  (target <= 5 us)")
    print(f"inline arithmetic median {inline_s * 1e6:7.3f} us/step")
    print(f"ratio step/inline        {step_s / inline_s:7.3f}     (target <= 1.5)")
    print(f"dynamic step      median {dynamic_s * 1e6:7.3f} us/step  (target <= 3 us)")
    print(f"ratio dynamic/paper step {dynamic_s / step_s:7.3f}")


if __name__ == "__main__":
    main()
