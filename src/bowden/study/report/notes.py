"""The report's notes, condensed: trial ids as runs, and one note per reason instead of one per trial.

The analysis writes a note per trial or per list of trials ("EMG of trials 1, 2, …, 204: recorded
with the trial", "trial 7 (participant P01, no_suit, V1) skipped: …"). A study of 204 trials made a
page of ids; the same facts fit in a line: "EMG of trials #1–#204: recorded with the trial".
"""

from __future__ import annotations

import re
from collections.abc import Iterable

from bowden.study.trial_list import id_ranges

# "trials 1, 2, 3" / "ids 4, 5": a list of two or more ids after a word that says they are trials.
_ID_LIST = re.compile(r"\b(trials|ids) (\d+(?:, \d+)+)\b")
# "trial 7 (participant P01, no_suit, V1) skipped: reason": one trial, then what happened to it.
_ONE_TRIAL = re.compile(r"^trial (\d+) \([^()]*\) (.+)$", re.S)
# More notes than this with the same text after their trial become one note listing the ids.
_GROUP_FROM = 3


def _runs(match: re.Match[str]) -> str:
    ids = [int(text) for text in match.group(2).split(", ")]
    return f"{match.group(1)} {id_ranges(ids)}"


def condense_notes(notes: Iterable[str]) -> list[str]:
    """``notes`` with id lists written as runs (``#1–#204``) and, where more than three trials share a
    note's text, one note for them all ("trials #3, #7–#9 (4 trials) skipped: …"), in the order of
    each text's first note."""
    notes = [_ID_LIST.sub(_runs, note) for note in notes]
    by_text: dict[str, list[int]] = {}
    for note in notes:
        match = _ONE_TRIAL.match(note)
        if match is not None:
            by_text.setdefault(match.group(2), []).append(int(match.group(1)))
    grouped = {text for text, ids in by_text.items() if len(ids) > _GROUP_FROM}
    condensed: list[str] = []
    for note in notes:
        match = _ONE_TRIAL.match(note)
        if match is None or match.group(2) not in grouped:
            condensed.append(note)
        elif int(match.group(1)) == by_text[match.group(2)][0]:
            ids = by_text[match.group(2)]
            condensed.append(f"trials {id_ranges(ids)} ({len(ids)} trials) {match.group(2)}")
    return condensed
