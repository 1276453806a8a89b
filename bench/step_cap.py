"""Label accuracy against one simulator setting over a model's parameter grid: how large a step cap can be before
the labels get worse (the evidence behind the pendulum's ``max_step_frac`` 0.03), or what a method costs in accuracy
(the RIMD's and the indenters' hybrids against DOPRI5).

Every grid point runs at the default rtol with each value of the setting (model defaults otherwise: adaptive
transient, window), and once with DOPRI5 at rtol 1e-11, the yardstick (the simulator itself: at 1e-11 the cap no
longer changes a label; the independent reference would take hours over a grid of long transients).  A point counts
when all runs settle on the yardstick's period; its error is the largest relative deviation of the force,
deceleration, impact-rate, energy and power labels from the yardstick.  Per value: the points counted, the accepted
steps summed over them, the median, 90th percentile and maximum error, and how many points exceed 1e-6.

Run: ``python -m bench.step_cap [--model pendulum] [--setting max_step_frac] [--values 0.02,0.03,0.05]
[--write-readme]`` (the pendulum: about 1 min per value on two cores).  Not a test: nothing asserts a timing or an
accuracy here.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
YARDSTICK_RTOL = 1e-11
KEYS = ("rop_m_s", "peak_force_n", "mean_peak_force_n", "peak_decel_g", "impacts_per_cycle", "energy_per_cycle_j", "power_w")
# the seed's gaps (MODELS.md §3 table) over the seed's impact resonances (1.5-8.5 Hz), the seed's A0 and about twice it
GRIDS = {"pendulum": {"gap_m": (0.0, 1.0e-3, 2.4e-3), "frequency_hz": tuple(np.arange(1.5, 8.51, 0.25)),
                      "amplitude_m": (0.89e-3, 2.0e-3)},
         # the seed's gaps (MODELS.md §4, seed Table 3) across its first impact resonances (5.5-8 Hz), F0 1 N and half
         "rimd": {"gap_m": (0.0, 1.0e-3, 3.0e-3), "frequency_hz": tuple(np.arange(4.0, 12.01, 0.5)),
                  "amplitude_n": (0.5, 1.0)}}
# the drill's lab preset (its default pipeline point) around its RED resonance, forcing up to 0.9 Pr, static force
# 0.3 and 0.6 Pr; the drill's DOPRI5 path (auto takes the exact propagator)
GRIDS["drill"] = {"frequency_hz": tuple(np.arange(100.0, 401.0, 50.0)), "amplitude_n": (900.0, 1800.0, 2700.0),
                  "static_force_n": (900.0, 1800.0)}
# the indenters across the seed's frequency range (MODELS.md §1, Table 1: 30-100 Hz), forcing over Table 1's range
# (220-900 N), and a tenth, the default and ten times the seal friction pm (whose tanh band the hybrid hands to DOPRI5)
for _m in ("indenter-metal", "indenter-sandstone"):
    GRIDS[_m] = {"frequency_hz": tuple(np.arange(30.0, 100.1, 10.0)), "amplitude_n": (220.0, 440.0, 880.0),
                 "pm": (2.0, 20.0, 200.0)}
PRESETS = {"drill": "lab"}
FIXED = {"drill": {"method": "dopri5"}}
DEFAULT_VALUES = {"max_step_frac": "0.02,0.025,0.03,0.035,0.04,0.05", "method": "dopri5,exact"}


def markers(model: str, setting: str) -> tuple[str, str]:
    """The bench/README.md markers between which the table of ``model`` and ``setting`` stands."""
    return f"<!-- step-cap:{model}:{setting}:start -->", f"<!-- step-cap:{model}:{setting}:end -->"


def grid_table(model: str):
    """Every combination of the model's ``GRIDS`` entry, as a DataFrame of parameter overrides."""
    import itertools

    import pandas as pd

    g = GRIDS[model]
    return pd.DataFrame([dict(zip(g, map(float, v))) for v in itertools.product(*g.values())])


def label_error(row, ref) -> float:
    """Largest relative deviation of the ``KEYS`` labels of ``row`` from ``ref`` (both label mappings)."""
    worst = 0.0
    for k in KEYS:
        v, u = row.get(k), ref.get(k)
        if v is None or u is None or not (np.isfinite(v) and np.isfinite(u)):
            continue
        worst = max(worst, abs(v - u) / max(abs(u), 1e-12))
    return worst


def study(model: str, values: list, setting: str = "max_step_frac") -> list[dict]:
    """Per value of ``setting``: points counted, steps, and the error statistics against the rtol-1e-11 yardstick."""
    import sim

    table = grid_table(model)
    preset, fixed = PRESETS.get(model), FIXED.get(model, {})
    ref = sim.simulate_batch(model, table, preset=preset, settings={"rtol": YARDSTICK_RTOL, "method": "dopri5"})
    runs = {c: sim.simulate_batch(model, table, preset=preset, settings={**fixed, setting: c}) for c in values}
    keep = (ref["status"] == "ok") & ref["period"].notna() & (ref["period"] > 0)
    for df in runs.values():
        keep &= (df["status"] == "ok") & (df["period"] == ref["period"])
    out = []
    for c, df in runs.items():
        errs = np.array([label_error(df.loc[i], ref.loc[i]) for i in table.index[keep]])
        out.append({"value": c, "points": int(keep.sum()), "grid": len(table), "steps": int(df.loc[keep, "n_steps"].sum()),
                    "median": float(np.median(errs)), "p90": float(np.quantile(errs, 0.9)), "max": float(errs.max()),
                    "over_1e-6": int((errs > 1e-6).sum())})
    return out


def render(model: str, rows: list[dict], command: str, setting: str = "max_step_frac") -> str:
    g = GRIDS[model]
    grid = ", ".join(f"{k} {min(v):g}–{max(v):g} ({len(v)})" for k, v in g.items())
    base = rows[0]["steps"]
    lines = [f"Generated by `{command}`: {model} over {grid}; default rtol 1e-7; error = largest relative deviation of "
             f"{', '.join(KEYS)} from the same point with DOPRI5 at rtol {YARDSTICK_RTOL:g}, over the {rows[0]['points']} of "
             f"{rows[0]['grid']} points where every run settles on the yardstick's period.", "",
             f"| {setting} | steps (vs first) | median error | 90th percentile | max | points > 1e-6 |",
             "|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['value']} | {r['steps']} ({r['steps'] / base:.2f}) | {r['median']:.2e} | {r['p90']:.2e} | "
                     f"{r['max']:.2e} | {r['over_1e-6']} |")
    return "\n".join(lines)


def _values(spec, setting: str, text: str) -> list:
    """The comma-separated values of ``setting``, each checked by the simulator's own settings validation."""
    from sim.api import Settings, make_settings
    from sim import ParameterError

    numeric = not isinstance(getattr(Settings(), setting), str)
    out = []
    for v in (x.strip() for x in text.split(",") if x.strip()):
        val = v
        if numeric:
            try:
                val = float(v)
            except ValueError:
                raise SystemExit(f"--values {text}: {setting} takes numbers, got {v!r}") from None
        try:
            make_settings(spec, {setting: val})
        except ParameterError as e:
            raise SystemExit(f"--values {text}: {e}") from None
        out.append(val)
    if not out:
        raise SystemExit(f"--values {text}: expected comma-separated values of {setting}")
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.step_cap", description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog="examples:\n  python -m bench.step_cap --write-readme\n"
                                        "  python -m bench.step_cap --values 0.02,0.05\n"
                                        "  python -m bench.step_cap --model rimd --setting method --write-readme\n"
                                        "  python -m bench.step_cap --model indenter-metal --setting method --write-readme")
    ap.add_argument("--model", default="pendulum", help=f"model with a grid here: {', '.join(GRIDS)} (default pendulum)")
    ap.add_argument("--setting", default="max_step_frac", help="the simulator setting to vary (default max_step_frac)")
    ap.add_argument("--values", default=None,
                    help="comma-separated values of the setting (default: max_step_frac 0.02,...,0.05; method "
                         "dopri5,exact)")
    ap.add_argument("--write-readme", action="store_true", help="write the table into bench/README.md's markers")
    a = ap.parse_args(argv)
    if a.model not in GRIDS:
        raise SystemExit(f"--model {a.model}: no grid for it here; known: {', '.join(GRIDS)}")
    import sim
    from sim.api import SETTING_NAMES

    if a.setting not in SETTING_NAMES:
        raise SystemExit(f"--setting {a.setting}: not a simulator setting; known: {', '.join(SETTING_NAMES)}")
    text = a.values if a.values is not None else DEFAULT_VALUES.get(a.setting, "")
    values = _values(sim.get_model(a.model), a.setting, text)
    command = f"python -m bench.step_cap --model {a.model} --setting {a.setting} --values {','.join(map(str, values))}"
    table = render(a.model, study(a.model, values, a.setting), command, a.setting)
    print(table)
    if a.write_readme:
        from bench import write_block

        write_block(ROOT / "bench" / "README.md", *markers(a.model, a.setting), table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
