"""Engineering units for people: reports and commands show mm/s, kN, W, g instead of the code's SI names.

``ENGINEERING[name] = (label, unit, factor)``: a value of column/key ``name`` [SI] times ``factor`` is in ``unit``.
The other way, for data that arrive in a lab's units (``vibro import``): ``SI_UNITS[unit] = (quantity, size in SI)``,
``column_factor('force_n', 'kN') == 1000``; an unknown unit raises ``UnitError`` with a did-you-mean.
"""
from __future__ import annotations

from typing import Mapping

from sim.layout import G_ACCEL

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
    # what a computation cost (a diagnosis's report.json 'cost')
    "simulations": ("simulations", "", 1.0),
    "cpu_s": ("CPU time", "s", 1.0),
    "wall_s": ("wall time", "s", 1.0),
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


def spread_words(spread: Mapping) -> str:
    """``parameter spread ±a, model error ±b (held-out rms e %), combined ±c mm/s, 5-95 %`` of report.json's
    'spread' (``RopSpread.to_dict``, pipeline.optimise.robustness); a model error not given is said to be so."""
    _, unit, k = ENGINEERING["rop_m_s"]
    a = float(spread.get("parameter_half_width_m_s", 0.5 * (spread["p95_rop_m_s"] - spread["p5_rop_m_s"])))
    b, c = spread.get("model_error_half_width_m_s"), spread.get("combined_half_width_m_s")
    if b is None or c is None:
        return (f"parameter spread ±{a * k:.3g} {unit}, 5-95 %; model error not given (the rig file has no "
                f"model_error), so no combined spread")
    e = 100 * spread["model_error_rel"]
    what = ("sd of the empirical ROP correction, physics unknown" if spread.get("empirical_correction")
            else "held-out rms")
    return (f"parameter spread ±{a * k:.3g}, model error ±{b * k:.3g} ({what} {e:.3g} %), "
            f"combined ±{c * k:.3g} {unit}, 5-95 %")


def spread_sentence(spread: Mapping) -> str:
    """``ROP 3.61 mm/s at the recommendation on the corrected rig: parameter spread ...`` (report.json 'spread')."""
    _, unit, k = ENGINEERING["rop_m_s"]
    return (f"ROP {spread['nominal_rop_m_s'] * k:.4g} {unit} at the recommendation on the corrected rig, "
            f"{spread_words(spread)} over {spread['n_samples']} samples of its fitted parameters")


# ------------------------------------------------------------------------------------------ units to SI
G = G_ACCEL
"""[m/s²] per g: the project's one value (``sim.layout.G_ACCEL``, the one ``peak_decel_g`` is computed with), so a
peak read in g comes back as the same number of g; standard gravity 9.80665 differs by 0.03 %."""

SI_UNITS: dict[str, tuple[str, float]] = {
    # time [s]
    "s": ("time", 1.0), "ms": ("time", 1e-3), "us": ("time", 1e-6), "µs": ("time", 1e-6), "μs": ("time", 1e-6),
    "ns": ("time", 1e-9), "min": ("time", 60.0),
    # frequency [Hz]
    "Hz": ("frequency", 1.0), "kHz": ("frequency", 1e3),
    # acceleration [m/s²]
    "m/s2": ("acceleration", 1.0), "m/s^2": ("acceleration", 1.0), "m/s²": ("acceleration", 1.0),
    "mm/s2": ("acceleration", 1e-3), "mm/s^2": ("acceleration", 1e-3), "mm/s²": ("acceleration", 1e-3),
    "g": ("acceleration", G),
    # force [N]
    "N": ("force", 1.0), "kN": ("force", 1e3), "mN": ("force", 1e-3), "MN": ("force", 1e6),
    "lbf": ("force", 4.4482216152605),
    # length [m]
    "m": ("length", 1.0), "cm": ("length", 1e-2), "mm": ("length", 1e-3), "um": ("length", 1e-6),
    "µm": ("length", 1e-6), "μm": ("length", 1e-6), "in": ("length", 0.0254),
    # velocity [m/s] (rate of penetration)
    "m/s": ("velocity", 1.0), "mm/s": ("velocity", 1e-3), "m/min": ("velocity", 1 / 60),
    "mm/min": ("velocity", 1e-3 / 60), "m/h": ("velocity", 1 / 3600), "ft/h": ("velocity", 0.3048 / 3600),
    # a count or ratio
    "1": ("dimensionless", 1.0), "-": ("dimensionless", 1.0),
}
"""Unit name -> (quantity, its size in the quantity's SI unit): a value in ``unit`` times the factor is SI."""

QUANTITY_OF: dict[str, tuple[str, float]] = {
    "t_s": ("time", 1.0), "accel_m_s2": ("acceleration", 1.0), "force_n": ("force", 1.0), "disp_m": ("length", 1.0),
    "progression_m": ("length", 1.0), "frequency_hz": ("frequency", 1.0), "amplitude_n": ("force", 1.0),
    "amplitude_m": ("length", 1.0), "static_force_n": ("force", 1.0), "gap_m": ("length", 1.0),
    "duration_s": ("time", 1.0), "record_start_s": ("time", 1.0), "rop_m_s": ("velocity", 1.0),
    "peak_force_n": ("force", 1.0), "peak_decel_g": ("acceleration", G), "impacts_per_cycle": ("dimensionless", 1.0),
}
"""A column of the measured format (MODELS.md §7) -> (quantity, size of its unit in SI): ``peak_decel_g`` is in g."""


class UnitError(ValueError):
    """A unit that is unknown or of the wrong quantity (the message names the unit, not the file)."""


def _norm(unit: str) -> str:
    return "".join(str(unit).split()).replace("**", "^")


def _suggest(unit: str, quantity: str | None) -> str:
    import difflib

    pool = [u for u, (q, _) in SI_UNITS.items() if quantity is None or q == quantity]
    close = [u for u in pool if u.lower() == unit.lower()] or difflib.get_close_matches(unit, pool, n=1, cutoff=0.6)
    known = f"{quantity} units: {', '.join(pool)}" if quantity else "units: pipeline/core/units.py SI_UNITS"
    return f"({'did you mean ' + repr(close[0]) + '? ' if close else ''}{known})"


def _a(word: str) -> str:
    return ("an " if word[0] in "aeiou" else "a ") + word


def si_factor(unit: str, quantity: str | None = None) -> float:
    """Size of ``unit`` in SI (e.g. ``kN`` -> 1000); UnitError when unknown or not a ``quantity`` unit."""
    key = _norm(unit)
    if key not in SI_UNITS:
        raise UnitError(f"unknown unit '{unit}' {_suggest(key, quantity)}")
    q, f = SI_UNITS[key]
    if quantity is not None and q != quantity:
        raise UnitError(f"unit '{unit}' is {_a(q)} unit, not {_a(quantity)} unit {_suggest(key, quantity)}")
    return f


def column_factor(column: str, unit: str) -> float:
    """Factor from ``unit`` to the unit of measured-format column ``column`` (``force_n`` from ``kN``: 1000;
    ``peak_decel_g`` from ``m/s2``: 1/G); UnitError for a unit of another quantity or a column with no unit."""
    if column not in QUANTITY_OF:
        raise UnitError(f"column '{column}' has no known unit; give it as a plain number")
    quantity, size = QUANTITY_OF[column]
    return si_factor(unit, quantity) / size
