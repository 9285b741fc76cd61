"""A trial encoded as the store keeps it, ready to insert: the encoding can run where the trial was made.

The study's writer is one process (SQLite has one writer); compressing a trial's samples and sEMG is
most of the cost of storing it. :func:`encode_trial` does that part anywhere — in the worker that
simulated the trial — so the writer only inserts BLOBs, and a worker sends back about a megabyte of
chunks instead of a trial's frames.
"""

from __future__ import annotations

from dataclasses import dataclass

import pandas as pd

from bowden.store import emg_chunks, sample_chunks


@dataclass(frozen=True)
class EncodedTrial:
    """A trial's sample chunks and sEMG chunks (empty: no sEMG), as the store's tables take them."""

    samples: list[sample_chunks.EncodedChunk]
    emg: list[emg_chunks.EncodedEmgChunk]


def encode_trial(samples: pd.DataFrame, emg: pd.DataFrame | None = None) -> EncodedTrial:
    """Encode a trial's samples (``contracts.TRIAL_COLUMNS``) and optional sEMG.

    Raises
    ------
    StoreError
        The samples or the sEMG cannot be stored (a missing or non-numeric column, uneven sEMG...).
    """
    columns = sample_chunks.columns_from_frame(samples)
    return EncodedTrial(
        samples=sample_chunks.encode_samples(columns),
        emg=emg_chunks.encode_trial_emg(emg) if emg is not None else [],
    )
