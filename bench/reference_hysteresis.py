"""How the reference's contact hysteresis ETA_X biases the drill labels (the 1.4e-8 `lab` disagreement).

The reference (tests/reference_solutions.py) and the bench peers enter contact where x1 - xt crosses +ETA_X,
so every contact starts ETA_X / v1 late; the drill's damper force C1 v1 jumps at the onset, so a late contact
transfers a little less momentum.  This prints, for ETA_X = 1e-13, 1e-14 and 1e-15 m, the relative difference
of the reference's labels (DOP853, rtol 1e-12) from the exact propagator's on the `lab` and default points
(transient 60, window 16 cycles): linear in ETA_X if the hysteresis is the cause.

Run: ``python -m bench.reference_hysteresis``  (about a minute).  Not a test.
"""
from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

LABELS = ("rop_m_s", "peak_force_n", "peak_decel_g", "energy_per_cycle_j")


def main() -> None:
    import sim
    import tests.reference_solutions as ref_mod

    n, w = 60, 16
    saved = ref_mod.ETA_X
    print(f"{'point':8s} {'ETA_X [m]':>10s} " + " ".join(f"{k:>20s}" for k in LABELS))
    try:
        for preset in ("lab", None):
            params = {k: v for k, v in sim.get_model("drill").resolve(preset).items() if k not in ("P", "D")}
            ex = sim.simulate("drill", preset=preset,
                              settings={"min_transient": n, "max_transient": n, "window": w, "method": "exact"}).labels
            for eta in (1e-13, 1e-14, 1e-15):
                ref_mod.ETA_X = eta
                ref = ref_mod.reference_run("drill", params, n, w, method="DOP853", rtol=1e-12)
                rel = [(ref[k] - ex[k]) / abs(ex[k]) for k in LABELS]
                print(f"{preset or 'default':8s} {eta:10.0e} " + " ".join(f"{r:20.2e}" for r in rel))
    finally:
        ref_mod.ETA_X = saved


if __name__ == "__main__":
    main()
