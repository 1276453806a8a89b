"""Held-out out-of-library physics: eight more kinds of term, each written from a physical
description alone, on the reference models of ``tests/reference_solutions.py`` and simulated by its event-locating
integrator (scipy DOP853 with every switching surface located).  Each is a factory ``system -> (params -> model)``
like those of ``dynamics.py``; ``outside.py`` registers them, ``rigs.py`` gives each rig's default strength.
Every parameter at its "off" value (zero strength) gives the base model: bit for bit where the term is a
multiplicative or additive change of an expression, to the integrator's tolerance where it adds states.

contact laws
  contact_exponent     (indenter-metal, pendulum) the contact's elastic part is a free power of the penetration
                       δ: k δ → k δr (δ/δr)^nc (Hertz-like for nc = 1.5: a rounded tip or a curved load-cell cap),
                       the same stiffness k at the reference penetration δr.  nc [-] (1 = the model), delta_r [m].
                       (contact_power adds a δ^2.5 term to the linear law; this replaces the law's exponent.)
  unloading_hysteresis (indenter-metal, pendulum) the contact unloads along another curve than it loads: after
                       the peak penetration δm of an impact the elastic part is k δm (δ/δm)^nu (nu > 1: below
                       the loading line, the loop's area is lost as plastic / hysteretic work each impact), back
                       on the loading line if δ returns to δm; the surface recovers between impacts.  nu [-]
                       (1 = the model).  One discrete state: δm (set at the velocity reversal, cleared at release).
  rate_strength        (drill) the rock's failure threshold rises with the rate of failure (dynamic strength
                       increase): Pr → Pr (1 + eta_r ẋb) in phase III, so ẋb = (P − Pr)/(C1 + eta_r Pr) and the
                       bit feels Pr (1 + eta_r ẋb) ≥ Pr.  eta_r [s/m] (0 = the model).  The switching surfaces
                       are unchanged (ẋb = 0 ↔ P = Pr).  (tip_blunting moves Pr with the depth, rate_stiffening K1
                       with the bit's speed in phase II; neither touches the failing rock's strength vs its rate.)

supports and drives
  mount_mode           (indenter-metal, rimd) the sample / stop sits on a compliant mount with inertia: a mass
                       ms on a spring 1/cm ∥ damper (ratio zeta_m) to ground; the contact acts between the
                       impacting mass and the mounted mass (δ = x − gap − xs, its rate relative).  ms [kg],
                       cm [m/N] (0 = a rigid mount: the states stay at 0, the model exactly), zeta_m [-].  Two
                       states (xs, ẋs).  (load_path_mode hangs a mass on the impacting body, never on the stop.)
  drive_mode           (drill, rimd) a mode inside the drive: a hidden mass md on the driving body (the drill's
                       exciter M2, the RIMD's main beam m1, which carries the forcing and the hammer) through a
                       spring ∥ damper tuned to fd_hz, ratio zeta_d.  md [kg], fd_hz [Hz] (0 = uncoupled: the
                       labels of the model to the solver's tolerance), zeta_d [-].  Two states.

slow changes
  contact_wear         (indenter-metal, pendulum) the struck surface wears / dents away with the impact work:
                       the contact position recedes by s, ṡ = kw F max(δ̇, 0) (the work done pressing into the
                       surface, Archard-like), so δ = x − gap − s; s never decreases.  kw [m/J] (0 = the model).
                       One state.  (tip_blunting raises a strength with the progression; nothing in §6 moves a
                       contact position.)

losses
  power_damping        (drill, indenter-sandstone, rimd) a velocity-power loss in the suspension between the
                       impacting mass and its carrier (drill bit–exciter link, indenter armature flexure φ1, RIMD
                       hammer–beam spring): cp |v|^pd sign v on the relative
                       velocity v (pd = 3 on the rigs: an elastomer / squeeze-film loss that grows faster than
                       viscous and than quadratic drag).  cp [N (s/m)^pd] (0 = the model), pd [-].
  support_friction     (indenter-sandstone, pendulum, rimd) dry friction at another site than the tool's guides:
                       the shaker body's carriages on the ground (indenter m2), the pendulum's pivot (a torque
                       mu_s l), the RIMD beam's clamp (m1); −mu_s tanh(v / v_eps), v_eps = 1e-4 m/s as MODELS.md §1
                       regularises Coulomb friction.  mu_s [N] (0 = the model).
"""
from __future__ import annotations

import math

import numpy as np

from tests import reference_solutions as ref

_MODELS = {"indenter-metal": ref._IndenterMetal, "indenter-sandstone": ref._IndenterSandstone,
           "drill": ref._Drill, "pendulum": ref._Pendulum, "rimd": ref._Rimd}
ETA_X, ETA_V = ref.ETA_X, ref.ETA_V
V_EPS = 1e-4

KINDS_SYSTEMS = {"contact_exponent": ("indenter-metal", "pendulum"),
                 "unloading_hysteresis": ("indenter-metal", "pendulum"),
                 "rate_strength": ("drill",),
                 "mount_mode": ("indenter-metal", "rimd"),
                 "drive_mode": ("drill", "rimd"),
                 "contact_wear": ("indenter-metal", "pendulum"),
                 "power_damping": ("drill", "indenter-sandstone", "rimd"),
                 "support_friction": ("indenter-sandstone", "pendulum", "rimd")}
"""The systems each held-out kind applies to."""

KINDS_PARAMS = {"contact_exponent": ("nc", "delta_r"), "unloading_hysteresis": ("nu_h",),
                "rate_strength": ("eta_r",), "mount_mode": ("ms", "cm", "zeta_m"),
                "drive_mode": ("md", "fd_hz", "zeta_d"), "contact_wear": ("kw",),
                "power_damping": ("cp", "pd"), "support_friction": ("mu_s",)}
"""Each kind's parameters (names are part of the interface: the truth of a log holds them)."""


def _pop(params: dict, names) -> tuple[dict, list[float]]:
    params = dict(params)
    return params, [float(params.pop(n)) for n in names]


def _check(system: str, kind: str):
    if system not in KINDS_SYSTEMS[kind]:
        raise ValueError(f"{kind} does not apply to {system!r} (only {KINDS_SYSTEMS[kind]})")


# =====================================================================================================
# Kelvin-Voigt contacts (indenter-metal, pendulum) with a replaceable elastic shape and contact geometry
# =====================================================================================================
def _kv_class(system: str, kind: str):
    """A model of ``system`` (indenter-metal or pendulum) whose contact expression is
        E = k [(1 + α max(δ̇, 0)) s(δ; disc) + τ δ̇],  F = max(0, E) in contact,
    with δ = δ0 − off, δ̇ = δ̇0 − off', δ0 the model's penetration, and the kind's shape s / offset /
    states."""
    base = _MODELS[system]
    metal = system == "indenter-metal"

    class KV(base):
        hyst = kind == "unloading_hysteresis"
        n_extra = {"mount_mode": 2, "contact_wear": 1}.get(kind, 0)

        def __init__(self, params):
            names = KINDS_PARAMS[kind]
            params, vals = _pop(params, names)
            for n, v in zip(names, vals):
                setattr(self, n, v)
            super().__init__(params)
            self.kc = self.p["k1"] if metal else self.p["ki"]
            if kind == "contact_exponent" and not (self.nc > 0.0 and self.delta_r > 0.0):
                raise ValueError(f"contact_exponent: need nc > 0, delta_r > 0 (got {self.nc}, {self.delta_r})")
            if kind == "unloading_hysteresis" and not self.nu_h >= 1.0:
                raise ValueError(f"unloading_hysteresis: need nu_h >= 1 (got {self.nu_h})")
            if kind == "contact_wear" and not self.kw >= 0.0:
                raise ValueError(f"contact_wear: need kw >= 0 (got {self.kw})")
            if kind == "mount_mode":
                if not (self.ms > 0.0 and self.cm >= 0.0 and self.zeta_m >= 0.0):
                    raise ValueError(f"mount_mode: need ms > 0, cm >= 0, zeta_m >= 0 (got {self.ms}, {self.cm}, "
                                     f"{self.zeta_m})")
                self.km = 1.0 / self.cm if self.cm > 0.0 else 0.0
                self.cs = 2.0 * self.zeta_m * math.sqrt(self.km * self.ms)
            self.ix = len(self.scales)                     # after W and the sensor filter
            self.scales = list(self.scales) + {2: [1.0, self.Om], 1: [1.0], 0: []}[self.n_extra]

        # ---- geometry ----------------------------------------------------------------------------
        def _raw(self, y):
            """(δ0, δ̇0) of the model (scalar or vectorised)."""
            if metal:
                return y[0] - self.G, y[1]
            return self.l * np.sin(y[0]) - self.gap, self.l * y[1] * np.cos(y[0])

        def _off(self, y):
            if kind == "mount_mode":
                return y[self.ix], y[self.ix + 1]
            if kind == "contact_wear":
                return y[self.ix], 0.0 * y[self.ix]
            return 0.0, 0.0

        def _geo(self, y):
            d0, dd0 = self._raw(y)
            o, od = self._off(y)
            return d0 - o, dd0 - od

        def _ddd_free(self, t, y):
            """d²δ/dt² along the free flow (F = 0)."""
            if metal:
                a = self._body(t, y, 0.0)[1]
            else:
                th, om = y[0], y[1]
                thdd = self._thdd(t, th, om, 0.0)
                a = self.l * (thdd * math.cos(th) - om * om * math.sin(th))
            if kind == "mount_mode":        # the mount's own free acceleration
                a -= (-self.km * y[self.ix] - self.cs * y[self.ix + 1]) / self.ms
            return a

        # ---- elastic shape ------------------------------------------------------------------------
        def _shape(self, d, disc):
            if kind == "contact_exponent":
                dp = np.maximum(d, 1e-300)
                return np.where(d > 0.0, d * (dp / self.delta_r) ** (self.nc - 1.0), d)
            if self.hyst and disc is not None:
                return np.where(d > 0.0, disc * (np.maximum(d, 0.0) / disc) ** self.nu_h, d)
            return d

        def _dshape(self, d, disc):
            if kind == "contact_exponent" and d > 0.0:
                return self.nc * (d / self.delta_r) ** (self.nc - 1.0)
            if self.hyst and disc is not None and d > 0.0:
                return self.nu_h * (d / disc) ** (self.nu_h - 1.0)
            return 1.0

        def _g2(self, d, dd, disc):
            return (1.0 + self.alpha * np.maximum(dd, 0.0)) * self._shape(d, disc) + self.t_kv * dd

        def _ind(self, t, y, disc):
            d, dd = self._geo(y)
            return d, self._g2(d, dd, disc)

        def indicators(self, t, y):
            return self._ind(t, y, None)

        def _rates(self, t, y, disc):
            d, dd = self._geo(y)
            ddd = self._ddd_free(t, y)
            s = float(self._shape(d, disc))
            r2 = (1.0 + self.alpha * max(dd, 0.0)) * self._dshape(d, disc) * dd + self.t_kv * ddd
            if dd > 0.0:
                r2 += self.alpha * ddd * s
            return dd, r2

        def rates(self, t, y):
            return self._rates(t, y, None)

        def _F(self, y, disc):
            d, dd = self._geo(y)
            return max(0.0, self.kc * float(self._g2(d, dd, disc)))

        # ---- flow -----------------------------------------------------------------------------------
        def rhs(self, t, y, br, disc):
            F = self._F(y, disc) if br == 1 else 0.0
            if metal:
                return self._body(t, y, F)
            th, om = y[0], y[1]
            W = self.m * self.l * self.A0 * self.Om ** 2 * math.sin(self.Om * t) * math.cos(th) * om
            return [om, self._thdd(t, th, om, F), W]

        def initial_state(self):
            y, disc = super().initial_state()
            return np.concatenate([y, np.zeros(self.n_extra)]), disc

        def flow(self, br, disc):
            inner = super().flow(br, disc)
            if not self.n_extra:
                return inner
            ix = self.ix

            def fun(t, y):
                dy = inner(t, y)
                F = self._F(y, disc) if br == 1 else 0.0
                if kind == "contact_wear":
                    dy.append(self.kw * F * max(self._geo(y)[1], 0.0))
                elif self.km > 0.0:
                    dy.append(y[ix + 1])
                    dy.append((F - self.km * y[ix] - self.cs * y[ix + 1]) / self.ms)
                else:                       # a rigid mount: the states stay at 0
                    dy.extend([0.0, 0.0])
                return dy
            return fun

        def force(self, t, Y, br, disc):
            if br == 0:
                return np.zeros_like(t)
            d, dd = self._geo(Y)
            return np.maximum(self.kc * self._g2(d, dd, disc), 0.0)

        # ---- switching ------------------------------------------------------------------------------
        def classify(self, t, y, disc):
            g1, g2 = self._ind(t, y, disc)
            g = min(g1, g2)
            if g > self.eta:
                br = 1
            elif g < -self.eta:
                br = 0
            else:
                r1, r2 = self._rates(t, y, disc)
                active = [r for gi, r in ((g1, r1), (g2, r2)) if gi <= self.eta]
                br = 1 if min(active) > 0.0 else 0
            if br == 0:
                disc = None
            elif self.hyst and disc is None and self._geo(y)[1] < -ETA_V:
                disc = float(self._geo(y)[0])       # (re)gained contact while already unloading
            return br, y, disc

        def events(self, br, disc):
            eta = self.eta
            ind = self._ind
            if br == 0:
                return [(lambda t, y: np.minimum(*ind(t, y, disc)) - eta, 1.0)]
            evs = [(lambda t, y: np.minimum(*ind(t, y, disc)) + eta, -1.0)]
            if self.hyst:
                if disc is None:       # velocity reversal: unloading starts from the peak
                    evs.append((lambda t, y: self._geo(y)[1] + ETA_V, -1.0))
                else:                  # back on the loading line
                    evs.append((lambda t, y: self._geo(y)[0] - disc - ETA_X, 1.0))
            return evs

        def on_event(self, br, idx, t, y, disc):
            if self.hyst and br == 1 and idx == 1:
                disc = float(self._geo(y)[0]) if disc is None else None
            return y, disc

        if kind == "contact_wear":
            def progression(self, t, Y, br, disc):      # the surface's recession (the wear) [m]
                return Y[self.ix]

    KV.__name__ = f"{base.__name__}{''.join(w.title() for w in kind.split('_'))}"
    return KV


# =====================================================================================================
# RIMD: mount_mode, power_damping, support_friction
# =====================================================================================================
def _rimd_class(kind: str):
    base = ref._Rimd

    class R(base):
        def __init__(self, params):
            names = KINDS_PARAMS[kind]
            params, vals = _pop(params, names)
            for n, v in zip(names, vals):
                setattr(self, n, v)
            super().__init__(params)
            self.ix = len(self.scales)
            if kind == "drive_mode":
                _drive_init(self, "m1")
            if kind == "mount_mode":
                if not (self.ms > 0.0 and self.cm >= 0.0 and self.zeta_m >= 0.0):
                    raise ValueError("mount_mode: need ms > 0, cm >= 0, zeta_m >= 0")
                self.km = 1.0 / self.cm if self.cm > 0.0 else 0.0
                self.cs = 2.0 * self.zeta_m * math.sqrt(self.km * self.ms)
                self.scales = list(self.scales) + [1.0, self.Om]

        if kind == "mount_mode":
            def _geo(self, y):
                return y[2] - self.gap - y[self.ix], y[3] - y[self.ix + 1]

            def _Fi(self, y):
                d, dd = self._geo(y)
                if d <= 0.0:
                    return 0.0
                p = self.p
                return p["ki"] * (1.0 + self.alpha * max(y[3], 0.0)) * d ** p["ni"] * max(0.0, 1.0 + p["lambda_i"] * dd)

            def indicators(self, t, y):
                d, dd = self._geo(y)
                return d, self.LS * (1.0 + self.p["lambda_i"] * dd)

            def rates(self, t, y):
                a2 = self._acc(t, y, 0.0)[1]
                a_s = (-self.km * y[self.ix] - self.cs * y[self.ix + 1]) / self.ms if self.km > 0.0 else 0.0
                return y[3] - y[self.ix + 1], self.LS * self.p["lambda_i"] * (a2 - a_s)

            def force(self, t, Y, br, disc):
                if br == 0:
                    return np.zeros_like(t)
                p = self.p
                d, dd = self._geo(Y)
                d = np.maximum(d, 0.0)
                return (p["ki"] * (1.0 + self.alpha * np.maximum(Y[3], 0.0)) * d ** p["ni"]
                        * np.maximum(0.0, 1.0 + p["lambda_i"] * dd))

            def initial_state(self):
                y, disc = super().initial_state()
                return np.concatenate([y, [0.0, 0.0]]), disc

            def flow(self, br, disc):
                inner = super().flow(br, disc)
                ix = self.ix

                def fun(t, y):
                    dy = inner(t, y)
                    if self.km > 0.0:
                        F = self._Fi(y) if br == 1 else 0.0
                        dy.append(y[ix + 1])
                        dy.append((F - self.km * y[ix] - self.cs * y[ix + 1]) / self.ms)
                    else:
                        dy.extend([0.0, 0.0])
                    return dy
                return fun

        elif kind == "power_damping":
            def _pd_force(self, v):       # on the hammer, v = ẋ2 − ẋ1 (vectorised)
                return self.cp * np.abs(v) ** self.pd * np.sign(v)

            def _acc(self, t, y, Fi):
                a1, a2, w = super()._acc(t, y, Fi)
                f = float(self._pd_force(y[3] - y[1]))
                return a1 + f / self.p["m1"], a2 - f / self.p["m2"], w

            def accel(self, t, Y, br, disc):
                return super().accel(t, Y, br, disc) - self._pd_force(Y[3] - Y[1]) / self.p["m2"]

        elif kind == "drive_mode":     # a hidden mode of the main beam m1 (its acceleration is dy[1])
            def _acc(self, t, y, Fi):
                a1, a2, w = super()._acc(t, y, Fi)
                return a1 + self._fd(y) / self.p["m1"], a2, w

            initial_state, flow, _fd = _drive_methods(base, 1)

        else:   # support_friction: the beam's clamp
            def _acc(self, t, y, Fi):
                a1, a2, w = super()._acc(t, y, Fi)
                return a1 - self.mu_s * math.tanh(y[1] / V_EPS) / self.p["m1"], a2, w

    R.__name__ = f"_Rimd{''.join(w.title() for w in kind.split('_'))}"
    return R


# =====================================================================================================
# drill: rate_strength, power_damping, drive_mode
# =====================================================================================================
def _drill_class(kind: str):
    base = ref._Drill

    class D(base):
        def __init__(self, params):
            names = KINDS_PARAMS[kind]
            params, vals = _pop(params, names)
            for n, v in zip(names, vals):
                setattr(self, n, v)
            super().__init__(params)
            if kind == "rate_strength" and not self.eta_r >= 0.0:
                raise ValueError(f"rate_strength: need eta_r >= 0 (got {self.eta_r})")
            if kind == "drive_mode":
                _drive_init(self, "M2")

        if kind == "rate_strength":
            def _vb(self, P, Pr):
                return (P - Pr) / (self.p["C1"] + self.eta_r * Pr)

            def rhs(self, t, y, br, disc):
                dy = super().rhs(t, y, br, disc)
                if br == 2:
                    Pr = self._Pr(y)
                    vb = self._vb(self._P(y), Pr)
                    dy[7] = vb
                    dy[1] = dy[1] - self.eta_r * Pr * vb / self.p["M1"]
                return dy

            def force(self, t, Y, br, disc):
                F = super().force(t, Y, br, disc)
                if br == 2:
                    Pr = self._Pr_vec(Y)
                    F = F + self.eta_r * Pr * self._vb(self._P_vec(Y), Pr)
                return F

            def accel(self, t, Y, br, disc):
                a = super().accel(t, Y, br, disc)
                if br == 2:
                    Pr = self._Pr_vec(Y)
                    a = a - self.eta_r * Pr * self._vb(self._P_vec(Y), Pr) / self.p["M1"]
                return a

        elif kind == "power_damping":
            def _pd_force(self, v):       # on the bit, v = ẋ1 − ẋ2 (vectorised); pulls the bit back
                return self.cp * np.abs(v) ** self.pd * np.sign(v)

            def _link(self, y):
                return super()._link(y) + float(self._pd_force(y[1] - y[3]))

            def accel(self, t, Y, br, disc):
                return super().accel(t, Y, br, disc) - self._pd_force(Y[1] - Y[3]) / self.p["M1"]

        else:   # drive_mode on the exciter M2 (index 3: its acceleration)
            def rhs(self, t, y, br, disc):
                dy = super().rhs(t, y, br, disc)
                dy[3] = dy[3] + self._fd(y) / self.p["M2"]
                return dy

            initial_state, flow, _fd = _drive_methods(base, 3)

    D.__name__ = f"_Drill{''.join(w.title() for w in kind.split('_'))}"
    return D


def _drive_init(self, mass: str):
    """Check the drive_mode parameters of ``self`` (on its body ``mass``) and add the two states' scales."""
    if not (self.md > 0.0 and self.fd_hz >= 0.0 and self.zeta_d >= 0.0):
        raise ValueError(f"drive_mode: need md > 0, fd_hz >= 0, zeta_d >= 0 (got {self.md}, {self.fd_hz}, "
                         f"{self.zeta_d})")
    wd = 2.0 * math.pi * self.fd_hz
    self.kd = self.md * wd * wd
    self.cd = 2.0 * self.zeta_d * self.md * wd
    self.id_ = len(self.scales)
    self.scales = list(self.scales) + [1.0, self.Om]


def _drive_methods(base, ia: int):
    """initial_state, flow and the coupling force of a hidden mass on the body whose acceleration is dy[ia]:
    states (xd, ẋd) relative to that body, ẍd = −(kd xd + cd ẋd)/md − a_body."""
    def initial_state(self):
        y, disc = base.initial_state(self)
        return np.concatenate([y, [0.0, 0.0]]), disc

    def flow(self, br, disc):
        inner = base.flow(self, br, disc)
        i = self.id_

        def fun(t, y):
            dy = inner(t, y)
            dy.append(y[i + 1])
            dy.append(-self._fd(y) / self.md - dy[ia])
            return dy
        return fun

    def _fd(self, y):
        return self.kd * y[self.id_] + self.cd * y[self.id_ + 1]

    return initial_state, flow, _fd


# =====================================================================================================
# indenter-sandstone: power_damping, support_friction
# =====================================================================================================
def _sandstone_class(kind: str):
    base = ref._IndenterSandstone

    class S(base):
        def __init__(self, params):
            names = KINDS_PARAMS[kind]
            params, vals = _pop(params, names)
            for n, v in zip(names, vals):
                setattr(self, n, v)
            super().__init__(params)

        if kind == "power_damping":      # on the armature suspension, v = φ̇1 = ẋ1 − ẋ2
            def _pd_force(self, v):
                return self.cp * np.abs(v) ** self.pd * np.sign(v)

            def _body(self, t, y, Fr):
                dy = super()._body(t, y, Fr)
                f = float(self._pd_force(y[1] - y[3]))
                dy[1] = dy[1] - f / self.p["m1"]
                dy[3] = dy[3] + f / self.p["m2"]
                return dy

            def _a1_vec(self, t, Y, Fr):
                return super()._a1_vec(t, Y, Fr) - self._pd_force(Y[1] - Y[3]) / self.p["m1"]

        else:   # support_friction: the shaker body's carriages on the ground
            def _body(self, t, y, Fr):
                dy = super()._body(t, y, Fr)
                dy[3] = dy[3] - self.mu_s * math.tanh(y[3] / V_EPS) / self.p["m2"]
                return dy

    S.__name__ = f"_IndenterSandstone{''.join(w.title() for w in kind.split('_'))}"
    return S


# =====================================================================================================
# pendulum: support_friction (the pivot)
# =====================================================================================================
def _pendulum_friction():
    base = ref._Pendulum

    class P(base):
        def __init__(self, params):
            params, (self.mu_s,) = _pop(params, ("mu_s",))
            super().__init__(params)

        def _fric(self, om):          # θ̈ term of a pivot torque mu_s l against the swing
            return self.mu_s * np.tanh(self.l * om / V_EPS) / self.m / self.l

        def _thdd(self, t, th, om, Fi):
            return super()._thdd(t, th, om, Fi) - float(self._fric(om))

        def accel(self, t, Y, br, disc):
            return super().accel(t, Y, br, disc) - self.l * np.cos(Y[0]) * self._fric(Y[1])

    P.__name__ = "_PendulumSupportFriction"
    return P


def factory(kind: str, system: str):
    """``params -> model`` for ``reference_run``: ``system`` with the held-out ``kind``."""
    _check(system, kind)
    if system in ("indenter-metal", "pendulum") and kind in ("contact_exponent", "unloading_hysteresis",
                                                              "mount_mode", "contact_wear"):
        return _kv_class(system, kind)
    if system == "rimd":
        return _rimd_class(kind)
    if system == "drill":
        return _drill_class(kind)
    if system == "indenter-sandstone":
        return _sandstone_class(kind)
    if system == "pendulum" and kind == "support_friction":
        return _pendulum_friction()
    raise ValueError(f"{kind} on {system}: no implementation")
