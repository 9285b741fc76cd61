"""Test-wide settings.

Property-based tests draw new examples on every run where developers run them, so they keep finding
bugs; CI (``HYPOTHESIS_PROFILE=ci``, set by ``.ci/run``) draws the same examples every time, so a
landing never depends on luck. Tests never assert on wall time, so the deadline is off.
"""

import os

from hypothesis import settings

settings.register_profile("ci", derandomize=True, deadline=None, print_blob=True)
settings.register_profile("dev", deadline=None, print_blob=True)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "dev"))
