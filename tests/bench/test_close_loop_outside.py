"""``python -m bench.close_loop_outside``: what a corrected rig corrects with, and the table's cells (no simulation
is run here)."""
from __future__ import annotations

from bench.close_loop_outside import MODELS, correction_of, table


def test_a_rig_names_its_correction():
    assert correction_of({"model": "drill", "discrepancy": {"rock_rate_strength": 5.0}}) == \
        "discrepancy: rock_rate_strength"
    assert correction_of({"model": "drill", "empirical_correction": {"points": []}}) == "empirical"
    assert correction_of({"model": "drill", "parameters": {"K1": 5e8}}) == "none"


def test_table_reads_the_correction_and_older_rows():
    def model(rop: float) -> dict:
        return {"point": {"frequency_hz": 200.0, "static_force_n": 1500.0}, "true_rop_m_s": rop, "ratio": rop / 4e-3}

    new = {"name": "a", "box": {"frequency_hz": (100, 300)}, "true_best_rop_m_s": 4e-3, "empirical_adopted": False,
           "correction": "discrepancy: rock_rate_strength", **{m: model(3.6e-3) for m in MODELS}}
    old = {"name": "b", "box": {"frequency_hz": (100, 300)}, "true_best_rop_m_s": 4e-3, "empirical_adopted": True,
           **{m: model(4e-3) for m in MODELS}}
    lines = table([new, old]).splitlines()
    assert lines[2].startswith("| a | discrepancy: rock_rate_strength | 4 | 3.6 mm/s (90.0 %) at frequency_hz 200 |")
    assert lines[3].startswith("| b | empirical | 4 | 4 mm/s (100.0 %)")
