"""An IMU's LSL bridge in a process of its own, steered line by line on stdin (tests of lsl_imu).

    python lsl_imu_outlet.py NAME quaternion|elevation

prints "ready" once its outlet exists, then streams at 200 Hz what the last command said:
``down`` (arm hanging), ``up DEG`` (arm elevated DEG degrees), ``nan``, ``silent`` (no samples),
``stale S`` (samples time-stamped S seconds in the past, as a backlog after a dropout), ``quit``.
The orientation is computed here, independently of bowden: q = q_elevation(θ) ⊗ q_mounting, with
q_elevation a rotation about +y by −θ (the humerus (0, 0, −1) swings to (sin θ, 0, −cos θ)).
"""

import math
import sys
import threading
import time

import pylsl


def multiply(p, q):
    w1, x1, y1, z1 = p
    w2, x2, y2, z2 = q
    return (w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2)


def about(axis, angle):
    norm = math.sqrt(sum(a * a for a in axis))
    s = math.sin(angle / 2.0) / norm
    return (math.cos(angle / 2.0), axis[0] * s, axis[1] * s, axis[2] * s)


MOUNTING = about((0.2, 0.9, -0.4), math.radians(55.0))  # strapped on at an arbitrary angle


def main() -> None:
    name, kind = sys.argv[1], sys.argv[2]
    channels = 4 if kind == "quaternion" else 1
    info = pylsl.StreamInfo(name, "Orientation", channels, 200.0, pylsl.cf_float32, f"test-{name}")
    if kind == "elevation":
        info.desc().append_child("channels").append_child("channel").append_child_value("unit", "degrees")
    outlet = pylsl.StreamOutlet(info)
    state = {"mode": "down", "deg": 0.0, "lag": 0.0}

    def stream() -> None:
        while state["mode"] != "quit":
            time.sleep(0.005)
            if state["mode"] == "silent":
                continue
            theta = math.radians(state["deg"]) if state["mode"] in ("up", "stale") else 0.0
            if kind == "quaternion":
                sample = list(multiply(about((0.0, 1.0, 0.0), -theta), MOUNTING))
            else:
                sample = [math.degrees(theta)]
            if state["mode"] == "nan":
                sample = [math.nan] * channels
            outlet.push_sample(sample, pylsl.local_clock() - state["lag"])

    thread = threading.Thread(target=stream)
    thread.start()
    print("ready", flush=True)
    for line in sys.stdin:
        words = line.split()
        if not words:
            continue
        state["mode"] = words[0]
        if words[0] == "up":
            state["deg"], state["lag"] = float(words[1]), 0.0
        elif words[0] == "stale":
            state["lag"] = float(words[1])
        elif words[0] in ("down", "nan"):
            state["lag"] = 0.0
        print("ok", flush=True)
        if words[0] == "quit":
            break
    state["mode"] = "quit"
    thread.join()


if __name__ == "__main__":
    main()
