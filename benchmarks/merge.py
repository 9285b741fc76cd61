"""Cost of verifying a chunk before the rows' other copy is deleted (issue 27, item 8).

The recorder's writer merges its small chunks into a full one (16384 rows, 33 s at 500 Hz) beside
the control loop; ``bowden study``'s workers encode each trial. Both now decode the new chunk and
compare it bit for bit before letting the rows go. This prints, per full chunk of a recorded store,
the time to encode it (the merge before the check) and to encode and check it (the merge now),
median and worst over the store's chunks, each taken as the best of ``--repeat`` runs.

    bowden run --backend sim --record rec.db --duration 70 --participant P01 --condition support_50 --speed V2
    python benchmarks/merge.py rec.db [--repeat 5]
"""

from __future__ import annotations

import argparse
import sqlite3
import statistics
import time
from collections.abc import Callable
from pathlib import Path

from bowden.contracts import TRIAL_COLUMNS
from bowden.store.column_codec import decode_columns
from bowden.store.sample_chunks import CHUNK_ROWS, Columns, encode_chunk, faithful_chunk


def best_of(repeat: int, work: Callable[[], object]) -> float:
    """The shortest of ``repeat`` runs of ``work`` (s): the cost without the host's interruptions."""
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        work()
        times.append(time.perf_counter() - start)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("store", type=Path, help="a store with at least one full chunk of samples")
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    with sqlite3.connect(args.store) as db:
        query = "SELECT data FROM sample_chunks WHERE row_count = ?"
        blobs = [blob for (blob,) in db.execute(query, (CHUNK_ROWS,))]
    if not blobs:
        raise SystemExit(f"{args.store} holds no full chunk of {CHUNK_ROWS} rows: record at least 33 s")
    blocks: list[Columns] = []
    for blob in blobs:
        columns = decode_columns(blob)
        blocks.append({name: columns[name] for name in TRIAL_COLUMNS})
    encode_chunk(blocks[0])  # load zstd once
    before = [best_of(args.repeat, lambda block=block: encode_chunk(block)) for block in blocks]
    after = [best_of(args.repeat, lambda block=block: faithful_chunk(block)) for block in blocks]
    print(f"{len(blocks)} full chunk(s) of {CHUNK_ROWS} rows from {args.store}")
    for label, times in (("encode (merge before the check)", before), ("encode + decode + compare", after)):
        print(f"  {label:<34} median {1e3 * statistics.median(times):6.2f} ms, "
              f"worst {1e3 * max(times):6.2f} ms")
    extra = statistics.median(a - b for a, b in zip(after, before, strict=True))
    print(f"  the check adds {1e3 * extra:.2f} ms a merge "
          f"({100 * extra / statistics.median(before):.0f} % of the encoding), once every {CHUNK_ROWS} rows")


if __name__ == "__main__":
    main()
