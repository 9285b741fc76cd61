"""The guard against numba reusing a batch-kernel cache compiled with older plant kernels."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

from bowden.control import command
from bowden.sim import _batch_kernel as bk
from bowden.sim import _controller_kernel as ck
from bowden.sim import _kernels as k
from bowden.sim._kernels import drop_stale_dependent_cache


def fake_dispatcher(cache_dir: Path) -> SimpleNamespace:
    return SimpleNamespace(_cache=SimpleNamespace(_cache_path=str(cache_dir)))


def test_cache_is_dropped_when_a_source_changes_and_kept_otherwise(tmp_path: Path) -> None:
    module, kernels = tmp_path / "trial.py", tmp_path / "kernels.py"
    module.write_text("def run(): ...\n")
    kernels.write_text("GAIN = 1\n")
    cache = tmp_path / "__pycache__"
    cache.mkdir()
    entries = [cache / "trial.run-3.py311.nbi", cache / "trial.run-3.py311.1.nbc"]
    unrelated = cache / "other.run-3.py311.nbi"
    for entry in (*entries, unrelated):
        entry.write_bytes(b"compiled")
    dispatcher = fake_dispatcher(cache)
    # First sight: no record of the sources the cache was made from, so it cannot be trusted.
    assert drop_stale_dependent_cache(dispatcher, str(module), str(kernels))
    assert not any(entry.exists() for entry in entries) and unrelated.exists()
    # Recompiled with the same sources: the cache stays.
    for entry in entries:
        entry.write_bytes(b"compiled")
    assert not drop_stale_dependent_cache(dispatcher, str(module), str(kernels))
    assert all(entry.exists() for entry in entries)
    # The kernels change (the module itself does not): its cache goes.
    kernels.write_text("GAIN = 2\n")
    assert drop_stale_dependent_cache(dispatcher, str(module), str(kernels))
    assert not any(entry.exists() for entry in entries) and unrelated.exists()


def test_without_a_numba_cache_nothing_happens(tmp_path: Path) -> None:
    module = tmp_path / "trial.py"
    module.write_text("x = 1\n")
    assert not drop_stale_dependent_cache(SimpleNamespace(), str(module))
    assert list(tmp_path.iterdir()) == [module]


def test_the_batch_kernel_cache_records_the_current_plant_kernels() -> None:
    # Importing the batch kernel ran the guard: the digest beside its cache is of today's sources.
    cache_path = getattr(getattr(bk.run_trial, "_cache", None), "_cache_path", None)
    assert isinstance(cache_path, str)
    marker = Path(cache_path) / "_batch_kernel.sources.sha256"
    assert marker.exists()
    sources = (k.__file__, ck.__file__, command.__file__)
    assert not drop_stale_dependent_cache(bk.run_trial, bk.__file__, *sources)
