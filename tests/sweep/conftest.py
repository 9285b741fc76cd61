"""A real two-worker local Dask cluster shared by the sweep tests, always closed at the end."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest

from bowden.sweep import SweepSpec

distributed = pytest.importorskip("distributed")


@pytest.fixture(scope="session")
def dask_client() -> Iterator[Any]:
    with (
        distributed.LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
        ) as cluster,
        distributed.Client(cluster) as client,
    ):
        yield client


@pytest.fixture(scope="session")
def small_spec() -> SweepSpec:
    """Two blends × two participants, two conditions at V3, two cycles per trial, the quick bench."""
    return SweepSpec(
        name="small",
        axes=(("blend_velocity_99_rad_s", (0.5, 1.0)),),
        participants=2,
        repetitions=2,
        conditions=("pretension", "support_50"),
        speeds=("V3",),
        bench="quick",
    )
