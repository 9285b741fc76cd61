"""The simulated bench's CAN traffic on ``bowden_loopback``, with and without acceptance filters.

Two motor nodes answer in a child process (as the simulated suit's do), each on its own thread; the
parent drives them as the bench's loop does, a command to each and its reply per cycle, with two
driver nodes. Printed: the time a cycle's two round trips take and the CPU both processes used per
cycle, with the motors' nodes unfiltered (every node woken for every frame) and filtered to their
own id (sim/link/suit_process.py), measured in one run, and their ratios.

    python benchmarks/loopback_can.py [--cycles 3000]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

import can

CHILD = """
import sys, threading, can
channel, filtered = sys.argv[1], sys.argv[2] == "1"
def serve(motor_id):
    filters = [{"can_id": motor_id, "can_mask": 0x7FF, "extended": False}] if filtered else None
    bus = can.Bus(interface="bowden_loopback", channel=channel, can_filters=filters)
    ready.release()
    while True:
        message = bus.recv(timeout=5.0)
        if message is None or message.data == b"stop":
            break
        if message.arbitration_id == motor_id and not message.is_extended_id:
            bus.send(can.Message(arbitration_id=0, data=bytes([motor_id]) + bytes(7), is_extended_id=False))
    bus.shutdown()
ready = threading.Semaphore(0)
threads = [threading.Thread(target=serve, args=(i,)) for i in (1, 2)]
for thread in threads:
    thread.start()
ready.acquire(); ready.acquire()
print("ready", flush=True)
for thread in threads:
    thread.join()
"""


def run(filtered: bool, cycles: int) -> tuple[float, float]:
    """Median round-trip time of a cycle (s) and CPU per cycle of both processes (s)."""
    with tempfile.TemporaryDirectory() as directory:
        channel = os.path.join(directory, "can")
        child = subprocess.Popen([sys.executable, "-c", CHILD, channel, "1" if filtered else "0"],
                                 stdout=subprocess.PIPE, text=True)
        assert child.stdout is not None and child.stdout.readline().strip() == "ready"
        drivers = [can.Bus(interface="bowden_loopback", channel=channel) for _ in range(2)]
        cpu0 = time.process_time()
        durations = []
        for _ in range(cycles):
            start = time.perf_counter()
            for motor_id, bus in zip((1, 2), drivers, strict=True):
                bus.send(can.Message(arbitration_id=motor_id, data=bytes(8), is_extended_id=False))
                while True:  # the reply to this command; the other motor's replies are skipped
                    reply = bus.recv(timeout=1.0)
                    assert reply is not None, "a simulated motor did not answer"
                    if reply.arbitration_id == 0 and reply.data[0] == motor_id:
                        break
            durations.append(time.perf_counter() - start)
            for bus in drivers:  # what the other driver's node queued (the loop's polls drain it)
                while bus.recv(timeout=0.0) is not None:
                    pass
        parent_cpu = time.process_time() - cpu0
        drivers[0].send(can.Message(arbitration_id=0x7FF, data=b"stop", is_extended_id=False))
        if filtered:  # the filtered nodes only hear their own ids
            for motor_id in (1, 2):
                drivers[0].send(can.Message(arbitration_id=motor_id, data=b"stop", is_extended_id=False))
        _, status, usage = os.wait4(child.pid, 0)  # the child's own CPU, as it ends
        assert os.waitstatus_to_exitcode(status) == 0, "the simulated motors' process failed"
        child.returncode = 0
        for bus in drivers:
            bus.shutdown()
    durations.sort()
    return durations[len(durations) // 2], (parent_cpu + usage.ru_utime + usage.ru_stime) / cycles


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cycles", type=int, default=3000)
    cycles = parser.parse_args().cycles
    results = {filtered: run(filtered, cycles) for filtered in (False, True)}
    for filtered, (round_trip, cpu) in results.items():
        label = "filtered  " if filtered else "unfiltered"
        print(f"{label}: a cycle's two round trips {round_trip * 1e3:.3f} ms (median), "
              f"CPU {cpu * 1e3:.3f} ms per cycle")
    (rt0, cpu0), (rt1, cpu1) = results[False], results[True]
    print(f"filtered / unfiltered: round trips {rt1 / rt0:.2f}, CPU {cpu1 / cpu0:.2f}")


if __name__ == "__main__":
    main()
