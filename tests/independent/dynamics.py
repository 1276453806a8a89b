"""Out-of-library dynamics on the reference models (``outside.py``): subclasses of the scipy reference's models
that add a term MODELS.md §6 does not have, simulated by the same event-locating integrator.

quadratic_damping (cq [N s²/m²]): a drag −cq v |v| on the impacting mass, v its velocity in the rig frame (the
indenter's armature x1, the drill bit x1, the RIMD hammer x2) or, for the pendulum, the hammer's swing speed l θ̇
(a tangential force, moment arm l).
"""
from __future__ import annotations

import numpy as np

from tests import reference_solutions as ref

_MODELS = {"indenter-metal": ref._IndenterMetal, "indenter-sandstone": ref._IndenterSandstone,
           "drill": ref._Drill, "pendulum": ref._Pendulum, "rimd": ref._Rimd}
# (index of the impacting mass's velocity in y, of its acceleration in dy, its mass parameter)
_MASS = {"indenter-metal": (1, "m1"), "indenter-sandstone": (1, "m1"), "drill": (1, "M1"), "rimd": (3, "m2"),
         "pendulum": (1, "m")}


def with_quadratic_damping(system: str):
    """A factory ``params -> model`` for ``reference_run``: ``system`` with the drag of parameter ``cq``."""
    base = _MODELS[system]
    iv, mass = _MASS[system]

    class QuadraticDamping(base):
        def __init__(self, params):
            params = dict(params)
            self.cq = float(params.pop("cq"))
            super().__init__(params)
            if system == "pendulum":      # θ̈ += −cq (l θ̇)|l θ̇| / (m l) = −cq l θ̇|θ̇| / m
                self.k_drag = self.cq * self.p["l"] / self.p["m"]
            else:
                self.k_drag = self.cq / self.p[mass]

        def rhs(self, t, y, br, disc):
            dy = super().rhs(t, y, br, disc)
            v = y[iv]
            dy[iv] = dy[iv] - self.k_drag * v * abs(v)
            return dy

        def accel(self, t, Y, br, disc):
            a = super().accel(t, Y, br, disc)
            v = Y[iv]
            drag = self.k_drag * v * np.abs(v)
            if system == "pendulum":       # absolute acceleration l (θ̈ cos θ − θ̇² sin θ) − A0 Ω² sin Ωt
                return a - self.p["l"] * drag * np.cos(Y[0])
            return a - drag

    QuadraticDamping.__name__ = f"{base.__name__}QuadraticDamping"
    return QuadraticDamping
