"""A command's log shows the warnings a user can act on: a library's deprecation notice about its own internals
is dropped, one raised in the project's code (something to fix here) and every other warning are shown once."""
from __future__ import annotations

import warnings

from pipeline.core.errors import show_warnings


def _caught(category, filename: str):
    return warnings.WarningMessage(f"{category.__name__} from {filename}", category, filename, 10)


def test_library_deprecations_are_dropped_and_the_rest_shown_once(capsys):
    import mlflow
    import pipeline.core.errors as own

    lib, mine = mlflow.__file__, own.__file__
    show_warnings([_caught(DeprecationWarning, lib), _caught(FutureWarning, lib), _caught(DeprecationWarning, mine),
                   _caught(RuntimeWarning, lib), _caught(RuntimeWarning, lib)])
    err = capsys.readouterr().err
    assert "from " + lib not in err.replace("RuntimeWarning from " + lib, "")
    assert f"DeprecationWarning from {mine}" in err and err.count(f"RuntimeWarning from {lib}") == 1
