"""Refusals in a command's own words: its flags, in its flags' units.

The runtime's classes check their fields and name them (``LoopConfig.rate_hz``, ``ServeConfig.port``);
a command that fills them from flags must say which flag was wrong. :func:`flag_errors` rewrites such a
refusal to name the flag, for fields in the flag's own unit (a flag in another unit, ms for a field in
s, is checked before it is converted, so the message shows the number the user typed).
"""

from __future__ import annotations

import re
from collections.abc import Iterator, Mapping
from contextlib import contextmanager

from bowden.errors import ParameterError


@contextmanager
def flag_errors(flags: Mapping[str, str]) -> Iterator[None]:
    """Re-raise a :class:`ParameterError` that names a field of ``flags`` with the flag's name instead.

    Parameters
    ----------
    flags
        Internal name as the messages spell it (``"LoopConfig.rate_hz"``, or a bare ``"time_scale"``)
        to the flag (``"--rate-hz"``). Only for fields in the flag's unit: the value quoted stays.
    """
    try:
        yield
    except ParameterError as error:
        text = str(error)
        for name, flag in flags.items():
            # A whole name only: "time_scale" must not match inside "SuitConfig.time_scale_max".
            pattern = rf"(?<![\w.]){re.escape(name)}(?!\w)"
            if re.search(pattern, text):
                raise ParameterError(re.sub(pattern, flag, text, count=1)) from None
        raise

