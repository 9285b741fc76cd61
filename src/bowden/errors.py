"""Every exception bowden raises on purpose.

Each subclasses a builtin so callers can catch what they understand (``ValueError`` for bad input,
``OSError`` for devices, ``TimeoutError`` for silent peers). Messages name the offending field,
column, row or device and say what to do about it. The command line turns any ``BowdenError``
into a one-line message and a non-zero exit code instead of a traceback.
"""

from __future__ import annotations


class BowdenError(Exception):
    """Base class of every error bowden raises deliberately."""


class ParameterError(BowdenError, ValueError):
    """A parameter is outside its valid range or of the wrong kind (names the field)."""


class ModelFileError(BowdenError, ValueError):
    """A ``model.json`` file is missing, malformed, of the wrong version or lacks a field."""


class RecordingError(BowdenError, ValueError):
    """A recording (bench, trial or EMG) is unusable: names the column and row of the problem."""


class FitError(BowdenError, ValueError):
    """A fit could not be made or did not converge (too little data, degenerate design)."""


class HardwareError(BowdenError, OSError):
    """A device misbehaved: wrong reply, error code, transmit failure."""


class DeviceTimeoutError(HardwareError, TimeoutError):
    """A device did not answer in time."""


class StoreError(BowdenError, RuntimeError):
    """The study store cannot be opened, read or written."""


class MalformedFrameError(HardwareError, ValueError):
    """A device sent bytes that do not decode (wrong length, bad OSC, wrong register size)."""


class TransmitError(HardwareError):
    """A frame could not be sent (e.g. CAN "No buffer space available": nothing on the bus ACKs)."""


class OutcomeTableError(BowdenError, ValueError):
    """An outcome table for the statistics is unusable (missing column, value <= 0, empty cell)."""


class OutputFileError(BowdenError, OSError):
    """An output file (model.json, figure, report) cannot be written: names the file and the reason."""


class RequestError(BowdenError, ValueError):
    """A request to the web server (operator console, questionnaire) is invalid: names the field."""


class AccessDeniedError(BowdenError, PermissionError):
    """A request lacks the session token (or carries a wrong one): nothing was changed."""


class ConflictError(BowdenError, RuntimeError):
    """A request conflicts with the current state (a trial already running, answers already stored)."""


class MissingExtraError(BowdenError, ImportError):
    """An optional dependency is not installed: names the extra to install (``bowden[cluster]``)."""


class ClusterError(BowdenError, RuntimeError):
    """The Dask cluster cannot be reached, runs another bowden, or lost a task for good."""


class SyncError(RecordingError):
    """A recording's sync events (trigger edges, LSL markers) do not agree with the store's trials."""
