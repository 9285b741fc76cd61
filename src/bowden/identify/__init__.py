"""Transmission identification: bench recordings -> :class:`bowden.model.CompensationModel`.

The paper's friction identification ("Model identification") as a tool: read and validate bench
recordings, low-pass and select steady-state samples, fit one robust line per direction with
:func:`robustfit` (equal to MATLAB's), and wrap it all in the scikit-learn style
:class:`TransmissionIdentifier`.
"""

from bowden.identify.robustfit import RobustFit, robustfit

__all__ = [
    "RobustFit",
    "robustfit",
]
