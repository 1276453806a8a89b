"""`vibro sweep` / pipeline.datasets.sweep: spec validation, designs, resumable chunked datasets, Dask scale-out.

Tiny sweeps (12 points of the drill model defaults, short settings window 8 / max_transient 100)
keep these tests fast; the preset is None until the drill 'lab' preset lands.
"""
from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pipeline.core.errors import UserError
from pipeline.datasets.dask_backend import DaskBackend
from pipeline.datasets.runner import LocalBackend, run_sweep
from pipeline.datasets.spec import Range, design_points, make_spec, unit_design
from pipeline.datasets.store import load_dataset
from sim import ParameterError
from vibrobase.statuses import STATUSES

REPO = Path(__file__).resolve().parents[3]
SHORT = {"window": 8, "max_transient": 100}
VARY = {"frequency_hz": {"low": 10.0, "high": 400.0, "scale": "linear"},
        "amplitude_n": {"low": 0.0, "high": 3000.0, "scale": "linear"},
        "static_force_n": {"low": 75.0, "high": 1425.0, "scale": "linear"}}


def raw_spec(**kw) -> dict:
    d = {"model": "drill", "preset": None, "fixed": {}, "vary": VARY, "design": "sobol", "n_points": 12,
         "seed": 0, "settings": SHORT, "chunk_size": 5}
    d.update(kw)
    return d


@pytest.fixture(scope="module")
def clean(tmp_path_factory) -> pd.DataFrame:
    """The uninterrupted reference run of raw_spec() (12 points, 3 chunks of 5/5/2)."""
    out = tmp_path_factory.mktemp("clean") / "ds"
    s = run_sweep(make_spec(raw_spec()), out, progress=False)
    assert s.computed == 12 and s.reused == 0
    return load_dataset(out)


# ------------------------------------------------------------------------------- validation
@pytest.mark.parametrize("change, words", [
    ({"vary": {**VARY, "foo": {"low": 1, "high": 2}}}, ["unknown parameter 'foo'"]),
    ({"fixed": {"K9": 1.0}}, ["unknown parameter 'K9'"]),
    ({"vary": {"frequency_hz": {"low": 50.0, "high": 50.0}}}, ["frequency_hz", "empty range"]),
    ({"vary": {"frequency_hz": {"low": 400.0, "high": 10.0}}}, ["frequency_hz", "inverted"]),
    ({"n_points": 0}, ["n_points", ">= 1"]),
    ({"n_points": -5}, ["n_points"]),
    ({"vary": {"amplitude_n": {"low": 0.0, "high": 10.0, "scale": "log"}}}, ["amplitude_n", "log"]),
    ({"vary": {"frequency_hz": {"low": 1.0, "high": 10.0, "scale": "cubic"}}}, ["frequency_hz.scale"]),
    ({"vary": {"frequency_hz": {"low": -10.0, "high": 10.0}}}, ["frequency_hz.low", "> 0"]),
    ({"vary": {}}, ["vary is empty"]),
    ({"design": "halton"}, ["design"]),
    ({"n_point": 3}, ["unknown key", "n_point"]),
    ({"settings": {"windw": 8}}, ["windw"]),
    ({"fixed": {"frequency_hz": 100.0}}, ["both fixed and varied"]),
    ({"design": "grid", "n_points": 10}, ["grid", "10"]),
    ({"preset": "no-such-preset"}, ["no-such-preset"]),
    ({"seed": 1.5}, ["seed"]),
])
def test_bad_spec_gives_clear_error_and_writes_nothing(tmp_path, change, words):
    out = tmp_path / "never"
    with pytest.raises((UserError, ParameterError)) as e:
        run_sweep(make_spec(raw_spec(**change)), out, progress=False)
    for w in words:
        assert w in str(e.value)
    assert not out.exists()


def test_cli_error_is_one_line_exit_2_and_writes_nothing(tmp_path, capsys):
    from pipeline.cli import main

    out = tmp_path / "never"
    rc = main(["sweep", "--preset", "none", "--vary", "frequency_hz=100:10", "--out", str(out), "--no-mlflow"])
    err = capsys.readouterr().err
    assert rc == 2
    assert err.count("\n") == 1 and "inverted range" in err and "Traceback" not in err
    assert not out.exists()


# ----------------------------------------------------------------------------------- designs
def test_sobol_not_power_of_two_is_prefix_of_the_power_of_two_sequence():
    from scipy.stats import qmc

    spec = make_spec(raw_spec(n_points=12))
    u = unit_design(spec)
    ref = qmc.Sobol(3, scramble=True, seed=0).random_base2(4)      # 16 = next power of 2 above 12
    assert u.shape == (12, 3)
    np.testing.assert_array_equal(u, ref[:12])
    assert not np.array_equal(u, unit_design(make_spec(raw_spec(n_points=12, seed=1))))


def test_lhs_is_stratified_and_points_respect_ranges_and_scales():
    spec = make_spec(raw_spec(design="lhs", n_points=20,
                              vary={"frequency_hz": {"low": 10.0, "high": 1000.0, "scale": "log"},
                                    "amplitude_n": {"low": 0.0, "high": 3000.0}}))
    u = unit_design(spec)
    for j in range(2):                          # one point in each 1/n stratum of every axis
        assert sorted(np.floor(u[:, j] * 20).astype(int)) == list(range(20))
    pts = design_points(spec)
    f = pts["frequency_hz"].to_numpy()
    assert f.min() >= 10.0 and f.max() <= 1000.0
    assert list(spec.vary) == ["amplitude_n", "frequency_hz"]      # dimensions in sorted name order
    np.testing.assert_allclose(np.log(f / 10.0) / np.log(100.0), u[:, 1], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(pts["amplitude_n"], 3000.0 * u[:, 0], rtol=1e-12)


def test_grid_levels_and_end_points():
    spec = make_spec(raw_spec(design="grid", n_points=12,
                              vary={"frequency_hz": {"low": 100.0, "high": 400.0, "levels": 4},
                                    "static_force_n": {"low": 100.0, "high": 1000.0, "scale": "log"}}))
    pts = design_points(spec)
    assert sorted(set(pts["frequency_hz"])) == [100.0, 200.0, 300.0, 400.0]
    np.testing.assert_allclose(sorted(set(pts["static_force_n"])), [100.0, (100.0 * 1000.0) ** 0.5, 1000.0])  # log: geometric mid-point
    assert len(pts.drop_duplicates(["frequency_hz", "static_force_n"])) == 12
    with pytest.raises(UserError, match="levels"):
        make_spec(raw_spec(design="sobol", vary={"frequency_hz": {"low": 1.0, "high": 2.0, "levels": 3}}))


def test_listing_order_of_vary_does_not_matter():
    a = make_spec(raw_spec())
    b = make_spec(raw_spec(vary=dict(reversed(list(VARY.items())))))
    assert a.fingerprint == b.fingerprint
    pd.testing.assert_frame_equal(design_points(a), design_points(b))


def test_default_sweep_is_the_drill_lab_preset_over_lab_space():
    """The shipped params.yaml 'sweep' section and the built-in default are the same spec (MODELS.md §2 lab space)."""
    from pipeline.core.params import read_section
    from sim.models.drill import LAB_SPACE

    spec = make_spec(read_section(REPO / "params.yaml", "sweep", section_required=True))
    assert spec.fingerprint == make_spec(None).fingerprint
    assert (spec.model, spec.preset, spec.design, spec.boundary_fraction) == ("drill", "lab", "sobol-boundary", 0.25)
    assert {k: (r.low, r.high) for k, r in spec.vary.items()} == {k: tuple(v) for k, v in LAB_SPACE.items()}


def test_range_to_physical_log():
    r = Range(1.0, 100.0, "log")
    np.testing.assert_allclose(r.to_physical(np.array([0.0, 0.5, 1.0])), [1.0, 10.0, 100.0])


def test_fingerprint_covers_spec_and_settings_not_chunk_size():
    base = make_spec(raw_spec())
    assert make_spec(raw_spec(chunk_size=7)).fingerprint == base.fingerprint
    assert make_spec(raw_spec(seed=1)).fingerprint != base.fingerprint
    assert make_spec(raw_spec(settings={"window": 9, "max_transient": 100})).fingerprint != base.fingerprint
    assert make_spec(raw_spec(fixed={"gap_m": 0.0})).fingerprint != base.fingerprint


# ------------------------------------------------------------------------- dataset contents
def test_dataset_columns_order_and_labels(clean):
    from sim import get_model
    from sim.api import DIAGNOSTICS, LABELS

    expected = ["point_id", *get_model("drill").param_names, *LABELS, "status", "reason", *DIAGNOSTICS]
    assert list(clean.columns) == expected
    assert clean["point_id"].tolist() == list(range(12))
    spec = make_spec(raw_spec())
    pts = design_points(spec)
    for name in spec.vary:                      # the inputs are the design points, exactly
        np.testing.assert_array_equal(clean[name].to_numpy(), pts[name].to_numpy())
    assert set(clean["status"]) <= set(STATUSES)
    meta = clean.attrs["metadata"]
    for key in ("model", "preset", "vary", "fixed", "design", "n_points", "seed", "fingerprint", "created",
                "git_commit", "versions", "wall_time_s", "status_counts", "settings"):
        assert key in meta, key
    assert meta["complete"] is True and meta["fingerprint"] == spec.fingerprint
    assert sum(meta["status_counts"].values()) == 12


def test_runaway_rows_kept_with_null_labels_not_nan(tmp_path):
    """Fs >= Pr (1500 N, drill default) is a runaway (MODELS.md §2): rows stay, labels are null in the file."""
    import pyarrow.compute as pc
    import pyarrow.parquet as pq

    out = tmp_path / "ds"
    spec = make_spec(raw_spec(n_points=8, chunk_size=8,
                              vary={"static_force_n": {"low": 1000.0, "high": 2000.0},
                                    "frequency_hz": {"low": 100.0, "high": 300.0}}))
    run_sweep(spec, out, progress=False)
    t = pq.read_table(out / "part-00000.parquet")
    status = t.column("status").to_pylist()
    fs = t.column("static_force_n").to_pylist()
    assert len(status) == 8
    assert [s == "runaway" for s in status] == [f >= 1500.0 for f in fs]
    assert "runaway" in status and "ok" in status
    for name in ("rop_m_s", "peak_force_n", "period", "energy_per_cycle_j"):
        col = t.column(name)
        assert col.null_count == status.count("runaway")
        assert not pc.any(pc.is_nan(col.drop_null())).as_py()
    reasons = [r for r, s in zip(t.column("reason").to_pylist(), status) if s == "runaway"]
    assert all("static force" in r for r in reasons)


# ---------------------------------------------------------------------- determinism / resume
def test_same_seed_same_dataset_any_chunking(tmp_path, clean):
    run_sweep(make_spec(raw_spec(chunk_size=12)), tmp_path / "a", progress=False, backend=LocalBackend(1))
    pd.testing.assert_frame_equal(load_dataset(tmp_path / "a"), clean, check_exact=True)
    other = tmp_path / "b"
    run_sweep(make_spec(raw_spec(seed=3, chunk_size=12)), other, progress=False)
    assert not np.array_equal(load_dataset(other)["frequency_hz"], clean["frequency_hz"])


class _Stop(KeyboardInterrupt):
    pass


def test_resume_after_interrupt_gives_the_clean_dataset(tmp_path, clean):
    out = tmp_path / "ds"
    spec = make_spec(raw_spec())

    def stop_after_first(k):
        raise _Stop()

    with pytest.raises(_Stop):
        run_sweep(spec, out, progress=False, _after_chunk=stop_after_first)
    assert sorted(p.name for p in out.glob("part-*.parquet")) == ["part-00000.parquet"]
    with pytest.raises(UserError, match="incomplete"):
        load_dataset(out)
    assert len(load_dataset(out, allow_partial=True)) == 5
    (out / ".part-00001.parquet.99999-k1ll3d.tmp").write_bytes(b"half-written garbage from a killed run")
    s = run_sweep(spec, out, progress=False)
    assert (s.reused, s.computed) == (5, 7)
    assert not list(out.glob(".part-*"))
    pd.testing.assert_frame_equal(load_dataset(out), clean, check_exact=True)
    meta = json.loads((out / "metadata.json").read_text())
    assert len(meta["sessions"]) == 2 and meta["complete"] is True
    s = run_sweep(spec, out, progress=False)          # complete: nothing more to do
    assert (s.reused, s.computed) == (12, 0)


@pytest.mark.slow
def test_resume_after_sigkill_of_the_cli(tmp_path, clean):
    """Kill -9 the real `vibro sweep` process after its first chunk file appears, then resume."""
    out = tmp_path / "ds"
    params = tmp_path / "params.yaml"
    import yaml

    params.write_text(yaml.safe_dump({"sweep": raw_spec()}))
    cmd = [sys.executable, "-m", "pipeline.cli", "sweep", "--params", str(params), "--out", str(out),
           "--no-mlflow", "--no-progress"]
    env = {**os.environ, "VIBRO_SWEEP_TEST_DELAY_S": "30"}     # test hook: sleep after each chunk
    proc = subprocess.Popen(cmd, cwd=REPO, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        deadline = time.time() + 120
        while not (out / "part-00000.parquet").exists():
            assert proc.poll() is None, proc.stderr.read().decode()
            assert time.time() < deadline, "no chunk written within 120 s"
            time.sleep(0.1)
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.stderr.close()
    assert proc.returncode == -signal.SIGKILL
    assert len(list(out.glob("part-*.parquet"))) == 1
    assert json.loads((out / "metadata.json").read_text())["complete"] is False
    assert (out / ".sweep.lock").exists()             # left behind by the killed process; must not block
    r = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "5 reused from disk" in r.stdout and "7 simulated" in r.stdout
    pd.testing.assert_frame_equal(load_dataset(out), clean, check_exact=True)


def test_changed_spec_is_refused_and_nothing_changes(tmp_path):
    out = tmp_path / "ds"
    spec = make_spec(raw_spec(n_points=4, chunk_size=4))
    run_sweep(spec, out, progress=False)
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    with pytest.raises(UserError, match=r"different spec.*seed: 0 -> 1"):
        run_sweep(make_spec(raw_spec(n_points=4, chunk_size=4, seed=1)), out, progress=False)
    with pytest.raises(UserError, match="chunk_size: 4 -> 2"):
        run_sweep(make_spec(raw_spec(n_points=4, chunk_size=2)), out, progress=False)
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    s = run_sweep(make_spec(raw_spec(n_points=4, chunk_size=4, seed=1)), out, progress=False, overwrite=True)
    assert s.computed == 4 and load_dataset(out).attrs["metadata"]["seed"] == 1


# --------------------------------------------------------------------------------- dask
def test_dask_localcluster_gives_identical_results_and_resumes(tmp_path, clean):
    """Chunks on a real LocalCluster (2 worker processes) == local run, bit for bit; a sweep
    interrupted locally is finished on the cluster with the same result."""
    from distributed import LocalCluster

    spec = make_spec(raw_spec())
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        addr = cluster.scheduler_address
        s = run_sweep(spec, tmp_path / "dask", backend=DaskBackend(addr), progress=False)
        assert s.computed == 12 and s.backend.startswith("dask")
        pd.testing.assert_frame_equal(load_dataset(tmp_path / "dask"), clean, check_exact=True)

        out = tmp_path / "mixed"

        def stop(k):
            raise _Stop()

        with pytest.raises(_Stop):
            run_sweep(spec, out, progress=False, _after_chunk=stop)
        s = run_sweep(spec, out, backend=DaskBackend(addr), progress=False)
        assert (s.reused, s.computed) == (5, 7)
        pd.testing.assert_frame_equal(load_dataset(out), clean, check_exact=True)


def test_unreachable_scheduler_is_a_user_error(tmp_path):
    with pytest.raises(UserError, match="cannot reach"):
        run_sweep(make_spec(raw_spec(n_points=2)), tmp_path / "ds", backend=DaskBackend("tcp://127.0.0.1:9"), progress=False)


# ----------------------------------------------------------------------------------- CLI
def test_cli_stage_writes_dataset_and_metrics(tmp_path, clean, capsys):
    import yaml

    from pipeline.cli import main

    params = tmp_path / "params.yaml"
    params.write_text(yaml.safe_dump({"sweep": raw_spec(), "train": {"whatever": 1}}))
    out, metrics, png = tmp_path / "ds", tmp_path / "m" / "sweep.json", tmp_path / "overview.png"
    rc = main(["sweep", "--params", str(params), "--out", str(out), "--metrics", str(metrics), "--no-progress",
               "--no-mlflow", "--plot", str(png)])
    assert rc == 0
    printed = capsys.readouterr().out
    assert "12 simulated, 0 reused" in printed and "sims/s" in printed
    pd.testing.assert_frame_equal(load_dataset(out), clean, check_exact=True)
    m = json.loads(metrics.read_text())
    assert m["n_points"] == 12 and sum(m["status_counts"].values()) == 12 and m["computed"] == 12
    assert m["status_counts"] == clean["status"].value_counts().to_dict() | {
        k: 0 for k in STATUSES if k not in set(clean["status"])}
    assert m["sims_per_s"] > 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # CLI flags override the params file: another seed into another directory
    rc = main(["sweep", "--params", str(params), "--out", str(tmp_path / "s1"), "--seed", "1", "--n-points", "4",
               "--no-progress", "--no-mlflow"])
    assert rc == 0 and load_dataset(tmp_path / "s1").attrs["metadata"]["seed"] == 1


@pytest.mark.slow
def test_cli_stage_writes_dataset_metrics_and_mlflow_run(tmp_path, monkeypatch, clean):
    import yaml

    from pipeline.cli import main

    monkeypatch.setenv("MLFLOW_TRACKING_URI", f"sqlite:///{tmp_path / 'mlflow.db'}")
    monkeypatch.setenv("VIBRO_EXPERIMENT", "test-sweep")
    monkeypatch.delenv("VIBRO_NO_MLFLOW", raising=False)
    params = tmp_path / "params.yaml"
    params.write_text(yaml.safe_dump({"sweep": raw_spec(), "train": {"whatever": 1}}))
    out, metrics = tmp_path / "ds", tmp_path / "m" / "sweep.json"
    rc = main(["sweep", "--params", str(params), "--out", str(out), "--metrics", str(metrics), "--no-progress"])
    assert rc == 0
    pd.testing.assert_frame_equal(load_dataset(out), clean, check_exact=True)
    m = json.loads(metrics.read_text())
    assert m["n_points"] == 12 and sum(m["status_counts"].values()) == 12 and m["computed"] == 12
    assert m["sims_per_s"] > 0
    import mlflow

    mlflow.set_tracking_uri(os.environ["MLFLOW_TRACKING_URI"])
    runs = mlflow.search_runs(experiment_names=["test-sweep"])
    assert len(runs) == 1
    assert runs.loc[0, "metrics.n_points"] == 12 and runs.loc[0, "params.design"] == "sobol"
    assert math.isclose(sum(runs.loc[0, f"metrics.count_{k}"] for k in STATUSES), 12)
    arts = {a.path for a in mlflow.MlflowClient().list_artifacts(runs.loc[0, "run_id"])}
    assert {"metadata.json", "sweep_overview.png"} <= arts


def _first_refused_by_loop(spec, cols: dict) -> int | None:
    import sim

    mspec = sim.get_model(spec.model)
    for i in range(len(next(iter(cols.values())))):
        try:
            mspec.resolve(spec.preset, **spec.fixed, **{k: float(v[i]) for k, v in cols.items()})
        except ParameterError:
            return i
    return None


@pytest.mark.parametrize("model", ["drill", "pendulum", "indenter-metal", "rimd"])
def test_vectorised_validation_agrees_with_resolve_row_by_row(model):
    """pipeline.datasets.spec.first_refused (column checks + resolve on the rows that decide) refuses a design
    exactly when resolving every row would, on hostile values (0, negatives, inf, nan, discrepancy terms the model
    lacks, a hidden mode without its frequency)."""
    import sim
    from pipeline.datasets.spec import first_refused
    from sim.models.discrepancy import PARAM_OF

    mspec = sim.get_model(model)
    spec = make_spec({"model": model, "vary": {"frequency_hz": {"low": 1.0, "high": 2.0}}, "n_points": 4})
    rng = np.random.default_rng(0)
    names = [p.name for p in mspec.params][:6] + [p for p in PARAM_OF if p in mspec.param_names][:4]
    hostile = np.array([0.0, -1.0, 1.0, 2.5, np.inf, np.nan, 1e-9])
    for trial in range(30):
        cols = {k: rng.uniform(0.5, 2.0, 50) * (mspec.defaults()[k] or 1.0) for k in names}
        for k in names:
            if k in PARAM_OF:
                cols[k][:] = 0.0
        if trial % 3:       # plant a few hostile cells
            for _ in range(int(rng.integers(1, 4))):
                k = names[int(rng.integers(len(names)))]
                cols[k][int(rng.integers(50))] = hostile[int(rng.integers(len(hostile)))]
        want = _first_refused_by_loop(spec, cols)
        got = first_refused(spec, cols)
        assert (got is None) == (want is None), (trial, want, got)


def test_ten_million_points_are_validated_in_seconds():
    from pipeline.datasets.spec import validate_points

    spec = make_spec(raw_spec(n_points=10_000_000, settings={}))
    pts = pd.DataFrame({"point_id": np.arange(spec.n_points)} | {k: np.full(spec.n_points, r.high)
                                                                   for k, r in spec.vary.items()})
    t0 = time.perf_counter()
    validate_points(spec, pts)
    assert time.perf_counter() - t0 < 20.0
    pts.loc[7_654_321, "frequency_hz"] = -1.0
    with pytest.raises(UserError, match="point 7654321 .*frequency_hz"):
        validate_points(spec, pts)
