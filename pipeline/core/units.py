"""Engineering units for people: reports and commands show mm/s, kN, W, g instead of the code's SI names.

``ENGINEERING[name] = (label, unit, factor)``: a value of column/key ``name`` [SI] times ``factor`` is in ``unit``.
"""
from __future__ import annotations

from typing import Mapping

ENGINEERING: dict[str, tuple[str, str, float]] = {
    "rop_m_s": ("ROP", "mm/s", 1e3),
    "frequency_hz": ("frequency", "Hz", 1.0),
    "amplitude_n": ("force amplitude F0", "kN", 1e-3),
    "amplitude_m": ("displacement amplitude", "mm", 1e3),
    "static_force_n": ("static force Fs", "kN", 1e-3),
    "gap_m": ("gap", "mm", 1e3),
    "peak_force_n": ("peak impact force", "kN", 1e-3),
    "mean_peak_force_n": ("mean peak force", "kN", 1e-3),
    "peak_decel_g": ("peak deceleration", "g", 1.0),
    "power_w": ("power", "W", 1.0),       # the lab rig exciter delivers 1-36 W over its search space (kW would print 0.013)
    "energy_per_cycle_j": ("energy per cycle", "J", 1.0),
    "specific_energy_j_m": ("specific energy", "kJ/m", 1e-3),
    "impacts_per_cycle": ("impacts per cycle", "", 1.0),
    "period": ("period", "cycles", 1.0),
    "spectral_ratio": ("spectral ratio", "", 1.0),
    "Pr": ("Pr (progression threshold)", "kN", 1e-3),
    # measured / simulated signals (time histories, spectra, bifurcation diagrams)
    "t_s": ("time", "ms", 1e3),
    "disp_m": ("displacement", "mm", 1e3),
    "progression_m": ("progression", "mm", 1e3),
    "force_n": ("contact force", "kN", 1e-3),
    "accel_m_s2": ("acceleration", "m/s²", 1.0),
    "peak_velocity_m_s": ("peak velocity", "m/s", 1.0),
}
SUFFIXES = ("_sim", "_pred", "_predicted", "_lo", "_hi", "_verified")
"""Name suffixes kept after the label: ``rop_m_s_sim`` -> ``ROP (sim) [mm/s]``."""


def split(name: str) -> tuple[str, str]:
    """(base quantity name, suffix) of a column/key, e.g. ``('rop_m_s', '_sim')``; suffix '' if none."""
    leaf = name.rsplit(".", 1)[-1]
    for suf in SUFFIXES:
        if leaf.endswith(suf) and leaf[: -len(suf)] in ENGINEERING:
            return leaf[: -len(suf)], suf
    if leaf.startswith("verified_") and leaf[9:] in ENGINEERING:
        return leaf[9:], "_verified"
    return leaf, ""


def label(name: str) -> str:
    """Human label with unit, e.g. ``rop_m_s_sim`` -> ``ROP (sim) [mm/s]``, ``best_rop_m_s`` -> ``best ROP
    [mm/s]``; unknown names unchanged."""
    leaf = name.rsplit(".", 1)[-1]
    if leaf.startswith("best_") and split(leaf[5:])[0] in ENGINEERING:
        return name[: len(name) - len(leaf)] + "best " + label(leaf[5:])
    base, suf = split(name)
    if base not in ENGINEERING:
        return name
    text, unit, _ = ENGINEERING[base]
    prefix = name.rsplit(".", 1)[0] + "." if "." in name and not name.startswith("params.") else ""
    return f"{prefix}{text}{f' ({suf[1:]})' if suf else ''}" + (f" [{unit}]" if unit else "")


def factor(name: str) -> float:
    """Factor from SI to the engineering unit of ``name`` (1 for unknown names)."""
    leaf = name.rsplit(".", 1)[-1]
    if leaf.startswith("best_") and split(leaf[5:])[0] in ENGINEERING:
        return factor(leaf[5:])
    base, _ = split(name)
    return ENGINEERING[base][2] if base in ENGINEERING else 1.0


def set_label(ax, which: str, name: str, text: str | None = None) -> float:
    """Label axis ``which`` ('x' or 'y') of matplotlib Axes ``ax`` with the
    quantity ``name`` from the table (``text`` replaces the words, the unit stays); returns the factor the
    plotted SI values must be multiplied by, so label and data take their unit from one place."""
    base = label(name)
    if text is not None:
        unit = base[base.rfind(" ["):] if base.endswith("]") else ""
        base = text + unit
    {"x": ax.set_xlabel, "y": ax.set_ylabel}[which](base)
    return factor(name)


def unit_of(text: str) -> str | None:
    """The unit in brackets at the end of an axis label (``'ROP [mm/s]'`` -> ``'mm/s'``), None without one."""
    return text[text.rfind("[") + 1:-1] if text.endswith("]") and "[" in text else None


def convert(name: str, value):
    """``value`` of ``name`` in engineering units (non-numbers unchanged)."""
    import numbers

    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        return value
    return value * factor(name)


def broken_words(broken: Mapping[str, Mapping]) -> str:
    """``power 19.1 W over its 18 W limit`` for each limit a point breaks (compare's ``breaks_on_<model>``), '' for none."""
    out = []
    for name, b in broken.items():
        label, v, lim = b.get("label"), b.get("value"), b.get("limit")
        if label in ENGINEERING and v is not None and lim is not None:
            words, unit, k = ENGINEERING[label]
            out.append(f"{words} {float(v) * k:.3g} {unit} over its {float(lim) * k:g} {unit} limit")
        else:
            out.append({"steady_state": "not in a steady state", "progress": "does not progress"}.get(name, name))
    return "; ".join(out)


SYMBOLS = {"frequency_hz": "f", "amplitude_n": "F0", "amplitude_m": "amplitude", "static_force_n": "Fs"}
"""Short names of the controls in an operating point (units from the table above)."""


def point_words(p: Mapping[str, float]) -> str:
    """``f = 262 Hz, F0 = 2.7 kN, Fs = 1.79 kN``: an operating point in engineering units."""
    return ", ".join(f"{SYMBOLS.get(k, k)} = {v * factor(k):.4g} {ENGINEERING.get(k, ('', ''))[1]}".rstrip()
                     for k, v in p.items())
