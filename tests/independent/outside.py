"""Physics outside MODELS.md §6, for the cases the diagnosis must call "unexplained".

  mount_resonance    the accelerometer sits on a resonant mount: measured acceleration = the true one through a
                     lightly damped 2nd-order resonance H(s) = wr²/(s² + 2 ζr wr s + wr²) (fr_hz, zeta_r); no §6
                     effect has a resonance (sensor_lowpass is a Butterworth, ζ = 0.71)
  quadratic_damping  a velocity-squared loss on the impacting mass (fluid / air drag): −cq v |v| [N]; the §6 losses
                     are viscous-like (shaker_coil β) or Coulomb (guide_friction) on a relative velocity
  contact_power      a contact law nonlinear in the penetration δ: the contact force expression gains
                     + kn max(δ, 0)^pn (kn [N/m^pn], pn [-], 2.5 on the rigs), inside the expression the model uses
                     for its force and its release / threshold indicators (``dynamics.with_contact_power``); drill,
                     indenter-metal, pendulum, rimd.  No §6 effect makes a contact stiffer with the penetration
                     itself: rate_stiffening scales the stiffness with the penetration *rate*, tip_blunting with the
                     progression, suspension_hardening hardens the suspension, not the contact.  Not on the
                     sandstone, whose base contact already has power-law branches with calibratable stiffnesses.
  load_path_mode     an extra mode in the load path: a hidden mass mh on the impacting mass through a spring ∥
                     damper tuned to fh_hz with damping ratio zeta_h (two more states; ``dynamics.with_load_path_mode``);
                     every system.  No §6 effect adds a degree of freedom with inertia: shaker_coil adds a first-order
                     force state, sensor_lowpass filters only what the sensor reports, the rest change force laws.

Held-out kinds (``kinds.py`` has the physics, the parameters and their units, ``rigs.py`` each
rig's default strength and the effect it has): contact_exponent, unloading_hysteresis, rate_strength (contact
laws); mount_mode, drive_mode (supports and drives); contact_wear (a slow change); power_damping,
support_friction (losses).  Each applies to the systems ``kinds.KINDS_SYSTEMS`` lists.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.signal import lsim


@dataclass(frozen=True)
class Outside:
    name: str
    measurement: bool           # True: changes only what the sensor reports

    def warmup_s(self, truth: dict) -> float:
        """How long before the record the sensor's dynamics must start (start-up below 1e-12) [s]."""
        if not self.measurement:
            return 0.0
        wr = 2.0 * math.pi * truth["fr_hz"]
        return 28.0 / (truth["zeta_r"] * wr)


OUTSIDE = {"mount_resonance": Outside("mount_resonance", True),
           "quadratic_damping": Outside("quadratic_damping", False),
           "contact_power": Outside("contact_power", False),
           "load_path_mode": Outside("load_path_mode", False),
           # held-out kinds (``kinds.py``): written from physical descriptions alone
           "contact_exponent": Outside("contact_exponent", False),
           "unloading_hysteresis": Outside("unloading_hysteresis", False),
           "rate_strength": Outside("rate_strength", False),
           "mount_mode": Outside("mount_mode", False),
           "drive_mode": Outside("drive_mode", False),
           "contact_wear": Outside("contact_wear", False),
           "power_damping": Outside("power_damping", False),
           "support_friction": Outside("support_friction", False)}


def measured_accel(name: str, truth: dict, t: np.ndarray, vel: np.ndarray, from_rest: bool) -> np.ndarray:
    """The sensor's output on the uniform grid ``t`` [s] from the impacting mass's velocity ``vel``: H(s) a =
    (s H(s)) v, with v linear between the samples (continuous, where the acceleration jumps at a contact's onset);
    from rest at t[0] (a record from rest starts its grid at t = 0, a steady-state one early enough)."""
    if name != "mount_resonance":
        raise ValueError(name)
    wr = 2.0 * math.pi * truth["fr_hz"]
    z = truth["zeta_r"]
    _, y, _ = lsim(([wr * wr, 0.0], [1.0, 2.0 * z * wr, wr * wr]), vel, t - t[0], interp=True)
    return np.asarray(y)


def model_for(system: str, outside: str | None):
    """What ``reference_run`` simulates: the system's own model, or its subclass with the outside dynamics."""
    if outside is None or OUTSIDE[outside].measurement:
        return system
    from tests.independent import dynamics, kinds

    if outside in kinds.KINDS_SYSTEMS:
        return kinds.factory(outside, system)
    factory = {"quadratic_damping": dynamics.with_quadratic_damping, "contact_power": dynamics.with_contact_power,
               "load_path_mode": dynamics.with_load_path_mode}[outside]
    return factory(system)
