"""Out-of-library dynamics on the reference models (``outside.py``): subclasses of the scipy reference's models
that add a term MODELS.md §6 does not have, simulated by the same event-locating integrator.

quadratic_damping (cq [N s²/m²]): a drag −cq v |v| on the impacting mass, v its velocity in the rig frame (the
indenter's armature x1, the drill bit x1, the RIMD hammer x2) or, for the pendulum, the hammer's swing speed l θ̇
(a tangential force, moment arm l).

contact_power (kn [N/m^pn], pn [-]): + kn max(δ, 0)^pn inside each contact force expression (and so in the
indicators that switch on it); drill, indenter-metal, pendulum, rimd (``with_contact_power``).

load_path_mode (mh [kg], fh_hz [Hz], zeta_h [-]): a hidden mass on a spring ∥ damper on the impacting mass, two
more states (``with_load_path_mode``); every system.
"""
from __future__ import annotations

import math

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


# ------------------------------------------------------------------------------------------------ contact_power
CONTACT_POWER_SYSTEMS = ("drill", "indenter-metal", "pendulum", "rimd")
"""The systems contact_power applies to (the sandstone's contact already has power-law branches)."""


def with_contact_power(system: str):
    """A factory ``params -> model`` for ``reference_run``: ``system`` with the contact force expression gaining
    ``+ kn max(δ, 0)**pn`` (parameters ``kn`` [N/m^pn], ``pn`` [-]) inside the expression the model uses for the
    force and for its release / threshold indicators, so the switching stays consistent with the force:

      drill           P = K1 (1 + α max(ẋ1, 0)) (x1 − xb) + C1 ẋ1 + kn max(x1 − xb, 0)^pn: the phase-II force, the
                      II→I (P = 0) and II→III (P = Pr) surfaces, classify (P and dP/dt), the phase-III slider law
                      ẋb = (P − Pr)/C1, and the free plate's relaxation C1 ẋt = −K1 (xt − xb) − kn max(xt − xb, 0)^pn
                      (the plate is the free end of the same spring ∥ damper: zero force while the bit is away, and
                      at x1 = xt d(x1 − xt)/dt = P / C1 as classify relies on)
      indenter-metal  Fr = max(0, k1 (1 + α max(ẋ1, 0)) (x1 − G) + c1 ẋ1 + kn max(x1 − G, 0)^pn), its force indicator
                      that expression / k1
      pendulum        Fi = max(0, ki (1 + α max(δ̇, 0)) δ + ci δ̇ + kn max(δ, 0)^pn), δ = l sin θ − gap; indicator / ki
      rimd            Fi = max(0, HC + kn max(δ, 0)^pn), HC the Hunt–Crossley ki (1 + α max(ẋ2, 0)) δ^ni
                      max(0, 1 + λ ẋ2), δ = x2 − gap; the indicators stay δ ≥ 0 and 1 + λ ẋ2 > 0
    (indenter-sandstone has power-law branches of its own: not applicable.)  With kn = 0 every expression is the
    base model's bit for bit.
    """
    if system not in CONTACT_POWER_SYSTEMS:
        raise ValueError(f"contact_power does not apply to {system!r} (only {CONTACT_POWER_SYSTEMS})")
    base = _MODELS[system]

    def pop(self, params):
        params = dict(params)
        self.kn = float(params.pop("kn"))
        self.pn = float(params.pop("pn"))
        if not (self.kn >= 0.0 and self.pn > 1.0):
            raise ValueError(f"contact_power: need kn >= 0 and pn > 1 (got kn={self.kn}, pn={self.pn})")
        return params

    if system == "drill":
        class ContactPower(base):
            def __init__(self, params):
                super().__init__(pop(self, params))

            def _P(self, y):
                return super()._P(y) + self.kn * max(y[0] - y[7], 0.0) ** self.pn

            def _P_vec(self, Y):
                return super()._P_vec(Y) + self.kn * np.maximum(Y[0] - Y[7], 0.0) ** self.pn

            def _Pdot(self, t, y, Pc):
                d = y[0] - y[7]
                extra = self.kn * self.pn * d ** (self.pn - 1.0) * y[1] if d > 0.0 else 0.0
                return super()._Pdot(t, y, Pc) + extra

            def rhs(self, t, y, br, disc):
                dy = super().rhs(t, y, br, disc)
                if br == 0:        # the free plate: C1 ẋt = −K1 (xt − xb) − kn max(xt − xb, 0)^pn
                    dy[6] = dy[6] - self.kn * max(y[6] - y[7], 0.0) ** self.pn / self.p["C1"]
                return dy

    elif system == "indenter-metal":
        class ContactPower(base):
            def __init__(self, params):
                super().__init__(pop(self, params))
                self.kn_k = self.kn / self.p["k1"]

            def _Fr(self, y):
                p = self.p
                return max(0.0, p["k1"] * (1.0 + self.alpha * max(y[1], 0.0)) * (y[0] - self.G) + p["c1"] * y[1]
                           + self.kn * max(y[0] - self.G, 0.0) ** self.pn)

            def indicators(self, t, y):
                g1, g2 = super().indicators(t, y)
                return g1, g2 + self.kn_k * np.maximum(y[0] - self.G, 0.0) ** self.pn

            def rates(self, t, y):
                r1, r2 = super().rates(t, y)
                d = y[0] - self.G
                if d > 0.0:
                    r2 += self.kn_k * self.pn * d ** (self.pn - 1.0) * y[1]
                return r1, r2

            def force(self, t, Y, br, disc):
                if br == 0:
                    return np.zeros_like(t)
                p = self.p
                return np.maximum(p["k1"] * (1.0 + self.alpha * np.maximum(Y[1], 0.0)) * (Y[0] - self.G)
                                  + p["c1"] * Y[1] + self.kn * np.maximum(Y[0] - self.G, 0.0) ** self.pn, 0.0)

    elif system == "pendulum":
        class ContactPower(base):
            def __init__(self, params):
                super().__init__(pop(self, params))
                self.kn_k = self.kn / self.p["ki"]

            def _Fi(self, th, om):
                p = self.p
                d = self.l * math.sin(th) - self.gap
                dd = self.l * om * math.cos(th)
                return max(0.0, p["ki"] * (1.0 + self.alpha * max(dd, 0.0)) * d + p["ci"] * dd
                           + self.kn * max(d, 0.0) ** self.pn)

            def indicators(self, t, y):
                g1, g2 = super().indicators(t, y)
                d = self.l * np.sin(y[0]) - self.gap
                return g1, g2 + self.kn_k * np.maximum(d, 0.0) ** self.pn

            def rates(self, t, y):
                r1, r2 = super().rates(t, y)
                d = self.l * math.sin(y[0]) - self.gap
                if d > 0.0:
                    r2 += self.kn_k * self.pn * d ** (self.pn - 1.0) * r1
                return r1, r2

            def force(self, t, Y, br, disc):
                if br == 0:
                    return np.zeros_like(t)
                p = self.p
                d = self.l * np.sin(Y[0]) - self.gap
                dd = self.l * Y[1] * np.cos(Y[0])
                return np.maximum(p["ki"] * (1.0 + self.alpha * np.maximum(dd, 0.0)) * d + p["ci"] * dd
                                  + self.kn * np.maximum(d, 0.0) ** self.pn, 0.0)

    else:   # rimd
        class ContactPower(base):
            def __init__(self, params):
                super().__init__(pop(self, params))

            def _Fi(self, y):
                d = y[2] - self.gap
                if d <= 0.0:
                    return 0.0
                return max(0.0, super()._Fi(y) + self.kn * d ** self.pn)

            def force(self, t, Y, br, disc):
                if br == 0:
                    return np.zeros_like(t)
                d = np.maximum(Y[2] - self.gap, 0.0)
                return np.maximum(super().force(t, Y, br, disc) + self.kn * d ** self.pn, 0.0)

    ContactPower.__name__ = f"{base.__name__}ContactPower"
    return ContactPower


# ------------------------------------------------------------------------------------------------ load_path_mode
def with_load_path_mode(system: str):
    """A factory ``params -> model`` for ``reference_run``: ``system`` with a hidden mass ``mh`` [kg] hung on the
    impacting mass (drill M1, indenter m1, RIMD m2, the pendulum's hammer: tangentially, at the hammer) by a spring
    kh ∥ damper ch, kh = mh (2π fh_hz)², ch = 2 zeta_h √(kh mh) (fh_hz: the mode's frequency with the impacting
    mass held).  Two extra states after all the model's own (W and the sensor filter included): xh, the hidden
    mass's position relative to the impacting mass, and ẋh.  The impacting mass feels + (kh xh + ch ẋh) (the
    pendulum: that tangential force over m l in θ̈), the hidden mass the reaction:
        ẍh = −(kh xh + ch ẋh)/mh − a_imp
    with a_imp the impacting mass's absolute acceleration (pendulum: the hammer's tangential one less the
    tangential gravity the hidden mass shares, l θ̈ − A0 Ω² sin Ωt cos θ + g sin θ).  Nothing switches on the
    hidden states; they ride through every event and restart.  Everything the model derives from the impacting
    mass's acceleration takes the coupling force: the rhs, the free-flow rates of the indicators (classify on a
    surface), the drill's dP/dt, the measured acceleration (``accel``, and the sensor filter via the rhs).
    """
    base = _MODELS[system]
    iv, mass = _MASS[system]

    class LoadPathMode(base):
        def __init__(self, params):
            params = dict(params)
            self.mh = float(params.pop("mh"))
            fh = float(params.pop("fh_hz"))
            zeta = float(params.pop("zeta_h"))
            if not (self.mh > 0.0 and fh >= 0.0 and zeta >= 0.0):
                raise ValueError(f"load_path_mode: need mh > 0, fh_hz >= 0, zeta_h >= 0 (got {self.mh}, {fh}, {zeta})")
            super().__init__(params)
            wh = 2.0 * math.pi * fh
            self.kh = self.mh * wh * wh
            self.ch = 2.0 * zeta * self.mh * wh
            if system == "pendulum":            # tangential force at the hammer -> θ̈ += f / (m l)
                self.inv_m = 1.0 / (self.p["m"] * self.p["l"])
            else:
                self.inv_m = 1.0 / self.p[mass]
            self.ih = len(self.scales)           # after W and the sensor filter
            self.scales = list(self.scales) + [1.0, self.Om]     # atol: metres, 1 mm * Om for the rate

        def _fh(self, y):
            return self.kh * y[self.ih] + self.ch * y[self.ih + 1]

        def initial_state(self):
            y, disc = super().initial_state()
            return np.concatenate([y, [0.0, 0.0]]), disc

        def flow(self, br, disc):
            inner = super().flow(br, disc)       # the model's rhs (with the coupling) and the sensor filter
            ih, mh = self.ih, self.mh

            def fun(t, y):
                dy = inner(t, y)
                f = self._fh(y)
                dy.append(y[ih + 1])
                dy.append(-f / mh - self._a_imp(t, y, dy))
                return dy
            return fun

        if system == "pendulum":
            def _a_imp(self, t, y, dy):
                th = y[0]
                return (self.l * dy[1] - self.A0 * self.Om ** 2 * math.sin(self.Om * t) * math.cos(th)
                        + self.p["g"] * math.sin(th))
        else:
            def _a_imp(self, t, y, dy):
                return dy[iv]

        # the coupling force on the impacting mass, wherever the model computes its acceleration
        if system in ("indenter-metal", "indenter-sandstone"):
            def _body(self, t, y, Fr):
                dy = super()._body(t, y, Fr)
                dy[1] = dy[1] + self._fh(y) * self.inv_m
                return dy

            def _a1_vec(self, t, Y, Fr):
                return super()._a1_vec(t, Y, Fr) + self._fh(Y) * self.inv_m

        elif system == "drill":
            def rhs(self, t, y, br, disc):
                dy = super().rhs(t, y, br, disc)
                dy[1] = dy[1] + self._fh(y) * self.inv_m
                return dy

            def _a1(self, t, y, Pc):
                return super()._a1(t, y, Pc) + self._fh(y) * self.inv_m

            def accel(self, t, Y, br, disc):
                return super().accel(t, Y, br, disc) + self._fh(Y) * self.inv_m

        elif system == "rimd":
            def _acc(self, t, y, Fi):
                a1, a2, w = super()._acc(t, y, Fi)
                return a1, a2 + self._fh(y) * self.inv_m, w

            def accel(self, t, Y, br, disc):
                return super().accel(t, Y, br, disc) + self._fh(Y) * self.inv_m

        else:   # pendulum
            def rhs(self, t, y, br, disc):
                dy = super().rhs(t, y, br, disc)
                dy[1] = dy[1] + self._fh(y) * self.inv_m
                return dy

            def rates(self, t, y):
                th, om = y[0], y[1]
                dd = self.l * om * math.cos(th)
                thdd = self._thdd(t, th, om, 0.0) + self._fh(y) * self.inv_m
                ddd = self.l * (thdd * math.cos(th) - om * om * math.sin(th))
                return ref._stiffened_rates(self.l * math.sin(th) - self.gap, dd, ddd, self.alpha, self.t_kv)

            def accel(self, t, Y, br, disc):      # horizontal: l cos θ × the θ̈ term
                return super().accel(t, Y, br, disc) + self._fh(Y) * self.inv_m * self.l * np.cos(Y[0])

    LoadPathMode.__name__ = f"{base.__name__}LoadPathMode"
    return LoadPathMode
