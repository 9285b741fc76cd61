"""The examples in the identification docstrings run and print what they claim."""

from __future__ import annotations

import doctest

import bowden.identify


def test_package_docstring_examples() -> None:
    result = doctest.testmod(bowden.identify, verbose=False)
    assert result.attempted >= 3
    assert result.failed == 0
