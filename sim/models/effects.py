"""Fit bounds of the MODELS.md §6 effect parameters, shared by every model that has the effect.

An effect is off at 0; a log10 fit approaches "off" by its lower bound, where it no longer changes the
response measurably (the bounds the diagnosis fits within).  A model may override a bound in its
own ``ModelSpec.effect_bounds``; a new effect parameter must be added here or there (ModelSpec checks).
"""
from __future__ import annotations

from sim.models.fitbound import FitBound

EFFECT_FIT_BOUNDS: dict[str, FitBound] = {b.name: b for b in (
    FitBound("tau", 1e-5, 1e-2, "s"),          # shaker_coil: coil current lag
    FitBound("beta", 1.0, 3e3, "N s/m"),       # shaker_coil: back-EMF damping
    FitBound("alpha", 1e-3, 30.0, "s/m"),      # rate_stiffening
    FitBound("mu", 0.1, 300.0, "N"),           # guide_friction
    FitBound("gamma", 1e-4, 0.5, "-"),         # tip_blunting
    FitBound("kappa", 1e2, 1e8, "1/m^2"),      # suspension_hardening
    FitBound("fc", 50.0, 5000.0, "Hz"),        # sensor_lowpass
)}
