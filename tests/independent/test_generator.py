"""The independent rig-log generator: independent of the project's code, §7-conformant logs, samples at the DAQ's
instants that agree with the simulator's, and noise models that do what they say."""
from __future__ import annotations

import ast
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tests.independent import noise as N
from tests.independent.generator import LogSpec, generate
from tests.independent.rigs import RIGS

pytestmark = pytest.mark.xdist_group("test_generator")   # one test worker builds the module's fixture

HERE = Path(__file__).resolve().parent
INDEPENDENT = [*HERE.glob("*.py"), HERE.parent / "reference_solutions.py"]


def _imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module:
            out.add(node.module.split(".")[0])
    return out


@pytest.mark.parametrize("path", [p for p in INDEPENDENT if not p.name.startswith("test_")], ids=lambda p: p.name)
def test_generator_shares_no_code_with_the_project(path):
    """Neither the generator nor the reference it runs imports sim, pipeline or surrogate (vibro synth included)."""
    assert not _imports(path) & {"vibrobase", "sim", "pipeline", "surrogate", "bench"}


def test_every_system_has_a_rig_with_every_effect_of_its_model():
    """The rigs cover every §6 effect the simulator declares for the model, plus at least one outside case."""
    import sim

    for name, rig in RIGS.items():
        assert set(rig.effects) == set(sim.get_model(name).effects), name
        assert rig.outside, name


@pytest.fixture(scope="module")
def drill_log(tmp_path_factory):
    """A 6-run drill log from rest (two DAQ rates, one summary-only run, one run without its force channel)."""
    out = tmp_path_factory.mktemp("gen") / "drill"
    info = generate(LogSpec("drill", noise="rig", seed=3, n_runs=6), out, threads=2)
    return out, info


def test_log_is_a_valid_section7_dataset(drill_log):
    from pipeline.datasets.measured import load_dataset

    out, info = drill_log
    ds = load_dataset(out)                       # the project's strict reader: every §7 rule
    runs = pd.read_csv(out / "runs.csv")
    assert len(runs) == 6 and set(runs["preset"]) == {"lab"} and runs["record_start_s"].notna().all()
    assert ds.summary is not None and len(ds.summary) >= 1 and len(ds.series) == 6 - len(ds.summary)
    rates = set()
    for rid, df in ds.series.items():
        dt = np.diff(df["t_s"].to_numpy())
        rates.add(round(1.0 / dt.mean()))
        f = runs.set_index("run_id").loc[rid, "frequency_hz"]
        assert abs(1.0 / dt.mean() / f - round(1.0 / dt.mean() / f)) > 1e-6      # not whole samples per cycle
    assert rates == {25600, 51200}
    assert any("force_n" not in df.columns for df in ds.series.values())       # a lost channel
    assert "rop_m_s_sd" in ds.summary.columns                                  # 'rig' noise: stated precision
    assert set(info["truth"]) == {"K1", "C1", "Pr"}


def test_samples_are_the_simulator_at_the_daq_instants(drill_log):
    """A run of the log without noise (rebuilt from the truth) equals sim.simulate sampled at the same instants
    (history_times) to 1e-5 of each signal's range: the generator's dynamics are the model's."""
    import sim
    from tests.independent.generator import RTOL, _run

    out, info = drill_log
    rig = RIGS["drill"]
    r = _run(rig, LogSpec("drill", noise="rig", seed=3, n_runs=6), info["truth"], 0, 150.0, 900.0, False)
    row = r["row"]
    times = row["record_start_s"] + r["t"]
    window = int(math.ceil((times[-1] + 1e-9) * 150.0)) + 1
    got = sim.simulate("drill", preset="lab", settings={"min_transient": 0, "max_transient": 0, "window": window,
                                                        "rtol": RTOL},
                       history_times=times, frequency_hz=150.0, amplitude_n=2250.0, static_force_n=900.0, gap_m=0.0,
                       **info["truth"]).history
    for sig in ("accel_m_s2", "force_n", "progression_m"):
        a, b = r["signals"][sig], got[sig].to_numpy()
        assert np.max(np.abs(a - b)) <= 1e-5 * np.ptp(b), sig


# ----------------------------------------------------------------------------- noise models
def _tone(n=20000, fs=10000.0):
    t = np.arange(n) / fs
    return t, 3.0 * np.sin(2 * np.pi * 50 * t) + 1.0


def test_noise_parts_do_what_they_say():
    rng = np.random.default_rng(0)
    t, x = _tone()
    rms = np.std(x)
    assert np.std(N.rms(x, 1e4, rng, "force_n", 0.02) - x) == pytest.approx(0.02 * rms, rel=0.03)
    assert np.std(N.white(x, 1e4, rng, "force_n") - x) == pytest.approx(N.SENSOR_FLOOR["force_n"], rel=0.03)
    g = N.gain(x, 1e4, rng, "force_n", 0.05) - x                    # proportional to the instantaneous signal
    assert np.std(g[np.abs(x) > 3.5]) > 3 * np.std(g[np.abs(x) < 0.5])
    q = N.quantise(x, 1e4, rng, "force_n", 8)
    lsb = 2 * 1.25 * np.abs(x).max() / 2 ** 8
    assert np.allclose(q / lsb, np.round(q / lsb)) and np.max(np.abs(q - x)) <= 0.5 * lsb + 1e-12
    p = N.pink(np.zeros_like(x), 1e4, rng, "force_n", 1.0) + 0.0
    spec = np.abs(np.fft.rfft(N.pink(x, 1e4, rng, "force_n", 0.1) - x)) ** 2
    fr = np.fft.rfftfreq(x.size, 1e-4)
    lo, hi = spec[(fr > 10) & (fr < 20)].mean(), spec[(fr > 1000) & (fr < 2000)].mean()
    assert 30 < lo / hi < 300                                         # 1/f: a decade and a half over 100x in f
    assert np.all(np.isfinite(p))
    o = N.offset(x, 1e4, rng, "force_n", 0.05) - x
    assert abs(o.mean()) > 0 and np.ptp(o) > 0                        # a constant offset and a drift


def test_summary_columns_rounded_or_stated():
    rng = np.random.default_rng(1)
    vals = {"peak_force_n": 1234.56789123, "rop_m_s": 0.00312345678}
    r = N.NOISE_MODELS["white2"].summary(vals, rng)
    assert r == {"peak_force_n": 1234.57, "rop_m_s": 0.00312346}          # 6 significant digits, no _sd
    s = N.NOISE_MODELS["rig"].summary(vals, rng)
    assert s["peak_force_n_sd"] == pytest.approx(0.03 * 1234.56789123, rel=1e-2) and "rop_m_s_sd" in s
