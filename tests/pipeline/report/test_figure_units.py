"""Every figure's axis unit matches the data it plots: each figure is drawn from SI data with known ranges, and
the range on every axis labelled with a quantity of pipeline.core.units must be that SI range times the factor of
the unit in the label (kN against N, mm/s against m/s: a factor 1000 off cannot pass)."""
from __future__ import annotations

from types import SimpleNamespace

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import pytest  # noqa: E402

from pipeline.core import units  # noqa: E402

RNG = np.random.default_rng(0)


def _quantity(text: str, names) -> str | None:
    """The quantity of ``names`` an axis label shows: the one with the label's unit (by its words when several
    share the unit); None for a label without a unit or one no quantity of ``names`` has."""
    unit = units.unit_of(text)
    hits = [n for n in names if unit is not None and units.label(n).endswith(f"[{unit}]")]
    if len(hits) > 1:
        hits = [n for n in hits if units.ENGINEERING[units.split(n)[0]][0] in text] or hits
    return hits[0] if hits else None


def check_units(fig, si: dict[str, tuple[float, float]]) -> int:
    """Assert every labelled axis of ``fig`` spans the SI range of its quantity (``si``) times the label's factor;
    the number of axes checked."""
    checked = 0
    for ax in fig.axes:
        for text, (lo, hi) in ((ax.get_xlabel(), ax.dataLim.intervalx), (ax.get_ylabel(), ax.dataLim.intervaly)):
            name = _quantity(text, si)
            if name is None:
                continue
            k = units.factor(name)
            elo, ehi = si[name][0] * k, si[name][1] * k
            span = ehi - elo
            assert elo - 0.6 * span <= lo and hi <= ehi + 0.6 * span and (hi - lo) >= 0.4 * span, (
                f"axis '{text}' plots {lo:.4g}..{hi:.4g}, but {name} {si[name]} [SI] is {elo:.4g}..{ehi:.4g} there")
            checked += 1
    plt.close(fig)
    return checked


def test_the_table_gives_one_factor_per_unit():
    by_unit: dict[str, set[float]] = {}
    for _, unit, f in units.ENGINEERING.values():
        by_unit.setdefault(unit, set()).add(f)
    assert {u: f for u, f in by_unit.items() if len(f) > 1} == {}


def test_the_check_catches_a_factor_1000():
    fig, ax = plt.subplots()
    ax.plot([100, 400], [3000.0, 5500.0])                 # N drawn under a kN label
    ax.set_xlabel(units.label("frequency_hz"))
    ax.set_ylabel(units.label("peak_force_n"))
    with pytest.raises(AssertionError, match="peak_force_n"):
        check_units(fig, {"frequency_hz": (100.0, 400.0), "peak_force_n": (3000.0, 5500.0)})


def test_diagnosis_summary_figure(monkeypatch):
    from pipeline.diagnosis.report import summary_figure
    from pipeline.diagnosis.result import SimulatedRun

    names = ["peak_force_n", "rop_m_s"]
    targets, runs = [], []
    for f in np.linspace(120.0, 420.0, 6):
        y = np.array([RNG.uniform(3000, 5500), RNG.uniform(0.0005, 0.0035)])
        targets.append(SimpleNamespace(kind="summary", names=names, controls={"frequency_hz": f}, y=y, sd=0.01 * y))
        runs.append(SimulatedRun(len(runs), np.zeros(2), None, y * RNG.uniform(0.95, 1.05, 2), None))
    ys = np.array([t.y for t in targets] + [r.model for r in runs])
    fig = summary_figure(targets, [("calibrated base", runs, "o")], "drill")
    si = {"frequency_hz": (120.0, 420.0), "peak_force_n": (ys[:, 0].min(), ys[:, 0].max()),
          "rop_m_s": (ys[:, 1].min(), ys[:, 1].max())}
    assert check_units(fig, si) == 4


def _capture(monkeypatch, module):
    figs = []
    monkeypatch.setattr(module, "atomic_write_figure", lambda path, fig, **kw: figs.append(fig) or path)
    return figs


def test_sweep_overview_and_report_time_history(monkeypatch):
    from pipeline.datasets import plot as dplot
    from pipeline.report import plots as rplots

    n = 40
    df = pd.DataFrame({"frequency_hz": RNG.uniform(100, 450, n), "amplitude_n": RNG.uniform(1800, 2700, n),
                       "rop_m_s": RNG.uniform(0.001, 0.008, n), "status": ["ok"] * n})
    import vibrobase.files as files

    figs = _capture(monkeypatch, files)
    dplot.plot_sweep(df, "frequency_hz", "amplitude_n", "x.png")
    assert check_units(figs.pop(), {"frequency_hz": (100, 450), "amplitude_n": (1800, 2700)}) == 2
    t = np.linspace(1.0, 1.05, 2000)
    hist = pd.DataFrame({"t_s": t, "disp_m": 1e-3 * np.sin(2e3 * t), "force_n": 4000 * np.abs(np.sin(1e3 * t)),
                         "accel_m_s2": 50 * np.sin(2e3 * t)})
    res = SimpleNamespace(history=hist, params={"frequency_hz": 200.0}, model="drill", status="ok",
                          labels={"impacts_per_cycle": 1, "period": 1})
    rplots.plot_time_history(res, "y.png")
    si = {"t_s": (0.0, 0.05), "disp_m": (-1e-3, 1e-3), "force_n": (0.0, 4000.0), "frequency_hz": (0.0, 2400.0)}
    assert check_units(figs.pop(), si) == 4              # time, displacement, force, spectrum frequency


def test_maps_and_optimisation_figures(monkeypatch, tmp_path):
    from pipeline.maps import compute as M
    from pipeline.maps import plot as mplot
    from pipeline.optimise import plots as oplots

    figs = _capture(monkeypatch, mplot)
    xs, ys = np.linspace(100, 450, 6), np.linspace(600, 1800, 5)
    grid = pd.DataFrame([{"ix": i, "iy": j, "frequency_hz": x, "static_force_n": y, "status": "ok",
                          "impacts_per_cycle": 1.0, "period": 1, "rop_m_s": 0.001 + 1e-5 * x, "peak_force_n": 3000 + y}
                         for i, x in enumerate(xs) for j, y in enumerate(ys)])
    grid = M.add_rop_region(M.add_pattern(grid))
    mplot.plot_rop(grid, "frequency_hz", "static_force_n", "r.png")
    mplot.plot_peterka(grid, "frequency_hz", "static_force_n", "p.png")
    si = {"frequency_hz": (100, 450), "static_force_n": (600, 1800), "peak_force_n": (3600, 4800),
          "rop_m_s": (0.002, 0.0055)}
    assert check_units(figs.pop(), si) == 5 and check_units(figs.pop(), si) == 3     # axes and colour bars
    points = pd.DataFrame({"direction": ["up"] * 6, "frequency_hz": xs, "peak_force_n": 3000 + 400 * np.arange(6)})
    strobe = pd.DataFrame({"direction": ["up"] * 6, "frequency_hz": xs, "disp_m": 1e-3 * np.arange(6)})
    mplot.plot_bifurcation(points, strobe, "frequency_hz", "b.png")
    assert check_units(figs.pop(), {"frequency_hz": (100, 450), "peak_force_n": (3000, 5000),
                                    "disp_m": (0.0, 5e-3)}) == 3
    trials = pd.DataFrame({"trial": range(20), "feasible": [True] * 20, "value": np.linspace(0.002, 0.008, 20),
                           "value_2": np.linspace(2.0, 30.0, 20)})
    saved = []
    monkeypatch.setattr(oplots, "_save", lambda fig, path: saved.append(fig) or str(path))
    oplots.plot_history(trials, tmp_path / "h.png", "h")
    assert check_units(saved.pop(), {"rop_m_s": (0.002, 0.008)}) == 1
    oplots.plot_pareto(trials, trials, None, tmp_path / "p.png", "p")
    assert check_units(saved.pop(), {"rop_m_s": (0.002, 0.008), "power_w": (2.0, 30.0)}) == 2
    table = pd.DataFrame({"rop_m_s_pred": np.linspace(0.002, 0.008, 5), "rop_m_s_sim": np.linspace(0.002, 0.008, 5),
                          "surrogate_wrong": [False] * 5})
    oplots.plot_verification(table, tmp_path / "v.png", "v")
    assert check_units(saved.pop(), {"rop_m_s_sim": (0.002, 0.008), "rop_m_s_pred": (0.002, 0.008)}) == 2


def test_training_parity_plot_in_the_applications_units(monkeypatch, tmp_path):
    """surrogate.plots draws in the display table it is given: training passes pipeline.core.units."""
    from surrogate import plots as splots

    n = 30
    test = pd.DataFrame({"rop_m_s": RNG.uniform(0.001, 0.008, n), "peak_force_n": RNG.uniform(3000, 5000, n)})

    class Bundle:
        regressors = {t: SimpleNamespace(name="gp", domain="all", transform=SimpleNamespace(kind="linear"))
                      for t in test.columns}
        report: dict = {}

        def predict(self, df, conditional=False):
            out = pd.DataFrame(index=df.index)
            for t in df.columns:
                out[t], out[f"{t}_lo"], out[f"{t}_hi"] = df[t] * 1.01, df[t] * 0.95, df[t] * 1.05
            return out

    saved = []
    monkeypatch.setattr(splots, "_save", lambda fig, path: saved.append(fig) or str(path))
    splots.parity(Bundle(), test, tmp_path / "parity.png", units.ENGINEERING)
    si = {"rop_m_s": (0.00095, 0.0084), "peak_force_n": (2850, 5250)}
    assert check_units(saved.pop(), si) == 4
