import doctest
import importlib


def test_emg_process_docstring_example_runs():
    # import_module: the package re-exports a function of the same name as the module.
    module = importlib.import_module("bowden.analysis.emg.process")
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS)
    assert result.attempted > 0
    assert result.failed == 0
