"""A p-value as the paper prints it: exact ("0.023") or an upper bound ("< 0.001")."""

from __future__ import annotations

from dataclasses import dataclass

from bowden.errors import ParameterError


@dataclass(frozen=True)
class P:
    """A published p-value, kept as printed so that a bound is never read as an exact value.

    ``P("< 0.001")`` has ``value`` 0.001 and ``upper_bound`` True: the paper says only that p lies
    below 0.001.
    """

    printed: str

    def __post_init__(self) -> None:
        try:
            value = float(self.printed.removeprefix("<").strip())
        except ValueError:
            raise ParameterError(f"not a p-value as printed: {self.printed!r}") from None
        if not 0.0 <= value <= 1.0:
            raise ParameterError(f"a p-value lies in [0, 1], got {self.printed!r}")

    @property
    def value(self) -> float:
        """The printed number (for a bound, the bound)."""
        return float(self.printed.removeprefix("<").strip())

    @property
    def upper_bound(self) -> bool:
        """True where the paper printed "< value"."""
        return self.printed.startswith("<")

    def significant(self, alpha: float = 0.05) -> bool:
        """p < ``alpha`` (a bound at or below ``alpha`` counts as significant)."""
        return self.value < alpha or (self.upper_bound and self.value <= alpha)

    def __float__(self) -> float:
        return self.value

    def __str__(self) -> str:
        return self.printed
