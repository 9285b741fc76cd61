import doctest

import bowden.analysis.emg_process


def test_emg_process_docstring_example_runs():
    result = doctest.testmod(bowden.analysis.emg_process, optionflags=doctest.ELLIPSIS)
    assert result.attempted > 0
    assert result.failed == 0
