"""The bottom package: light to import (every ``vibro --help`` imports its errors) and one base for bad input."""
from __future__ import annotations

import subprocess
import sys


def test_importing_the_light_modules_loads_no_numpy():
    code = ("import vibrobase, vibrobase.errors, vibrobase.statuses, vibrobase.files, vibrobase.jsonable, sys\n"
            "print(','.join(m for m in ('numpy', 'sim', 'surrogate', 'pipeline') if m in sys.modules))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == ""


def test_the_bad_input_errors_share_one_base_and_stay_value_errors():
    import sim
    from pipeline.core.errors import UserError
    from surrogate.errors import BundleError, SurrogateError
    from vibrobase.errors import InputError

    for cls in (sim.ParameterError, SurrogateError, BundleError, UserError):
        assert issubclass(cls, InputError) and issubclass(cls, ValueError), cls
    assert sim.ParameterError.__module__ == "sim.models.param"
