"""The EMG import's constants: channel maps, sync tolerances, trigger polarities.

They live apart from the modules that use them (:mod:`bowden.analysis.emg.channels`,
:mod:`bowden.analysis.emg.sync`, which need NumPy and pandas) so that ``bowden emg import``'s
choices and help text cost nothing to build: ``bowden --help`` imports no signal processing.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Final, Literal

from bowden.contracts import MUSCLES

# A TMSi SAGA recording the eight muscles on its first eight unipolar inputs (module docstring of
# bowden.analysis.emg.channels).
SAGA_CHANNELS: Final[Mapping[str, str]] = {
    f"UNI{i + 1}": muscle for i, muscle in enumerate(MUSCLES)
}
BUILT_IN_MAPPINGS: Final[Mapping[str, Mapping[str, str]]] = {"saga": SAGA_CHANNELS}

# Defaults of the import: a crystal beyond 200 ppm is broken or the events are mismatched, and a
# residual beyond 2 ms (4 samples at 2 kHz) means an edge that is not where the controller sent it.
DRIFT_TOLERANCE_PPM = 200.0
RESIDUAL_TOLERANCE_S = 2e-3

TriggerPolarity = Literal["auto", "high", "low"]
POLARITIES: tuple[TriggerPolarity, ...] = ("auto", "high", "low")
