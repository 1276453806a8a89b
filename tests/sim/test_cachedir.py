"""numba's cache of the simulator is keyed by every sim source (sim/cachedir.py): an edit anywhere in sim/ must not
load machine code compiled against the old sources (a module's constants read by another module's functions)."""
from __future__ import annotations

import shutil

from sim.cachedir import SIM_DIR, jit_cache_dir, source_digest


def test_the_digest_changes_with_any_sim_source(tmp_path):
    copy = tmp_path / "sim"
    shutil.copytree(SIM_DIR, copy, ignore=shutil.ignore_patterns("__pycache__"))
    before = source_digest(copy)
    assert source_digest(copy) == before
    f = copy / "models" / "drill.py"
    f.write_text(f.read_text() + "\n# an edit\n")
    assert source_digest(copy) != before


def test_jitted_sim_functions_cache_under_the_digest(monkeypatch):
    import numba

    from sim.models.contact import coulomb_sign

    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    assert coulomb_sign(0.0, 1.0) == 0.0          # compiles it (cache=True)
    assert numba.config.CACHE_DIR == str(jit_cache_dir())
    assert jit_cache_dir().name == f"jit-{source_digest()}"
