import asyncio
import itertools
import json
import math
import threading

from bowden.web.live import ROLE_CONSOLE, ROLE_DISPLAY, LiveHub, SampleTap, Thinning, encode


def test_rows_from_another_thread_arrive_in_order_with_few_wakeups():
    async def scenario():
        loop = asyncio.get_running_loop()
        wakes = []
        tap = SampleTap(loop, lambda: wakes.append(1))

        def producer():
            for i in range(1000):
                tap.record((i * 0.002, float(i)))

        thread = threading.Thread(target=producer)
        thread.start()
        thread.join()
        await asyncio.sleep(0)  # let the scheduled wake-up run
        rows = tap.drain()
        return rows, wakes

    rows, wakes = asyncio.run(scenario())
    assert [r[1] for r in rows] == list(range(1000))
    assert [r[2][1] for r in rows] == [float(i) for i in range(1000)]
    assert all(b[0] >= a[0] for a, b in itertools.pairwise(rows))  # wall stamps never go back
    assert len(wakes) == 1  # one wake-up for a batch that was not drained in between


def test_a_row_after_a_drain_wakes_the_server_again():
    async def scenario():
        wakes = []
        tap = SampleTap(asyncio.get_running_loop(), lambda: wakes.append(1))
        tap.record((0.0,))
        await asyncio.sleep(0)
        first = tap.drain()
        tap.record((0.002,))
        await asyncio.sleep(0)
        return first, tap.drain(), wakes

    first, second, wakes = asyncio.run(scenario())
    assert len(first) == len(second) == 1 and len(wakes) == 2


def test_thinning_keeps_every_fifth_row_of_500_hz_for_100_hz():
    thinning = Thinning(100.0)
    rows = [(0.0, i, (i / 500.0,)) for i in range(1000)]
    kept = thinning.keep(rows[:333]) + thinning.keep(rows[333:])  # across batches
    assert [r[1] for r in kept] == list(range(0, 1000, 5))


def test_thinning_250_hz_to_100_hz_keeps_100_rows_per_second():
    thinning = Thinning(100.0)
    kept = thinning.keep([(0.0, i, (i / 250.0,)) for i in range(2500)])
    assert len(kept) == 1000  # one per 10 ms slot over 10 s
    times = [r[2][0] for r in kept]
    assert max(b - a for a, b in itertools.pairwise(times)) <= 0.012 + 1e-12


def test_encode_turns_nan_into_null():
    text = encode({"a": [1.0, math.nan, math.inf], "b": {"c": -math.inf}})
    assert json.loads(text) == {"a": [1.0, None, None], "b": {"c": None}}


def test_roles_and_slow_clients():
    async def scenario():
        hub = LiveHub()
        display, console = hub.connect(ROLE_DISPLAY), hub.connect(ROLE_CONSOLE)
        hub.publish({"n": 0}, (ROLE_CONSOLE,))
        for n in range(300):
            hub.publish({"n": n}, (ROLE_DISPLAY,))
        hub.disconnect(display)
        hub.publish({"n": 999})
        return display, console, hub.count()

    display, console, remaining = asyncio.run(scenario())
    assert console.queue.qsize() == 2 and remaining == 1
    # The display's queue holds the newest 256 messages; the oldest were dropped, not the newest.
    assert display.dropped == 300 - 256
    assert json.loads(display.queue.get_nowait()) == {"n": 300 - 256}
