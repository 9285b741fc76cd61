"""What the browser pages call the conditions: words an operator reads in a sentence.

The paper's short labels (``contracts.CONDITION_LABELS``: "no", "pre", "25%", "50%") are column heads
of its tables; in the console's sentences they read as words ("Questionnaires due after no"). A lab's
own condition (``--define-condition``) is called by its name.
"""

from __future__ import annotations

from typing import Final

from bowden.contracts import (
    CONDITION_NO_SUIT,
    CONDITION_PRETENSION,
    CONDITION_SUPPORT_25,
    CONDITION_SUPPORT_50,
)

PAGE_LABELS: Final = {
    CONDITION_NO_SUIT: "no suit",
    CONDITION_PRETENSION: "pretension",
    CONDITION_SUPPORT_25: "25% support",
    CONDITION_SUPPORT_50: "50% support",
}


def condition_label(condition: str) -> str:
    """The label the pages show for ``condition`` (the paper's in words, a lab's by its name)."""
    return PAGE_LABELS.get(condition, condition)
