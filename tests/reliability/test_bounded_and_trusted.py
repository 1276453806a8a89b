"""Bounded work and inert bundles: every hostile input ends in exit 2 and one line naming the culprit,
quickly, without a signal and without writing anything; labels are null only with a failure status."""
from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from pipeline.cli import main

pytestmark = pytest.mark.xdist_group("test_bounded_and_trusted")   # one test worker builds the module's fixture

ROOT = Path(__file__).resolve().parents[2]
ALIAS_BOMB = "a: &a [x, x, x, x, x, x, x, x, x]\n" + "".join(
    f"{c}: &{c} [*{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}]\n" for p, c in zip("abcdefgh", "bcdefghi"))


@pytest.fixture(autouse=True)
def _no_mlflow(monkeypatch):
    monkeypatch.setenv("VIBRO_NO_MLFLOW", "1")


def _vibro(*args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    """The CLI in a child process (a crash shows as a negative return code, not a dead test run)."""
    env = {**os.environ, "VIBRO_NO_MLFLOW": "1"}
    return subprocess.run([sys.executable, "-m", "pipeline.cli", *args], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=timeout)


def _one_line_exit_2(rc: int, err: str, *words: str) -> None:
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert rc == 2, err
    assert len(lines) == 1, err
    for w in words:
        assert w in lines[0], lines[0]


# ----------------------------------------------------------------------------- crafted bundles
def _rehash(d: Path) -> None:
    man = json.loads((d / "manifest.json").read_text())
    for name, rec in man["files"].items():
        b = (d / name).read_bytes()
        rec.update(sha256=hashlib.sha256(b).hexdigest(), size=len(b))
    (d / "manifest.json").write_text(json.dumps(man))


def _break_tree(b) -> None:
    tree = b.classifier.estimators_[0].tree_
    st = tree.__getstate__()
    nodes = st["nodes"].copy()
    nodes["left_child"][0] = 10**7
    tree.__setstate__({**st, "nodes": nodes})


def _break_predictor(b) -> None:
    b.regressors["rop_m_s"].estimator._predictors[0][0].nodes["right"][0] = 10**7


def _break_feature(b) -> None:
    b.regressors["rop_m_s"].estimator._predictors[0][0].nodes["feature_idx"][0] = 99


@pytest.fixture(scope="module")
def tree_bundle(tmp_path_factory) -> Path:
    """A bundle whose classifier is extra trees (sklearn Tree) and regressors histogram boosting (TreePredictor)."""
    from surrogate import train_bundle
    from tests.surrogate.test_surrogate import RANGES, synthetic

    cfg = {"regressors": ["gbt"], "classifiers": ["trees"], "cv_folds": 2, "learning_curve": [1.0]}
    d = tmp_path_factory.mktemp("tb") / "surrogate"
    train_bundle(synthetic(100), list(RANGES), RANGES, "drill", None, cfg).save(d)
    return d


def test_honest_tree_bundle_loads_and_predicts(tree_bundle):
    import pandas as pd

    from surrogate import load_bundle
    from surrogate.bundle import TRUSTED_TYPES
    from surrogate.tree_check import CHECKED_TYPES, check_trees

    assert not set(CHECKED_TYPES) & set(TRUSTED_TYPES)     # tree storage is never trusted unchecked
    b = load_bundle(tree_bundle)
    assert check_trees(b, len(b.inputs)) > 10
    out = b.predict(pd.DataFrame({"frequency_hz": [200.0], "amplitude_n": [1500.0]}))
    assert out["regime"].iloc[0] in ("progressing", "no_progress")


@pytest.mark.parametrize("damage, words, child", [
    (_break_tree, "left child 10000000", True),
    (_break_predictor, "right child 10000000", False),
    (_break_feature, "feature 99", False),
])
def test_crafted_tree_bundle_is_one_line_exit_2_never_a_signal(tree_bundle, tmp_path, capsys, damage, words, child):
    """In a child process for one damage (a signal would show as a negative return code); the others in this
    process, through the same command and check."""
    import skops.io as sio

    from surrogate import load_bundle

    d = tmp_path / "evil"
    d.mkdir()
    for f in tree_bundle.iterdir():
        (d / f.name).write_bytes(f.read_bytes())
    b = load_bundle(d)
    damage(b)
    (d / "bundle.skops").write_bytes(sio.dumps(b))
    _rehash(d)                                              # a valid manifest: only the node check stands
    args = ("optimise", "--surrogate", str(d), "--out", str(tmp_path / "o"), "--no-mlflow", "--quiet",
            "--storage", f"sqlite:///{tmp_path / 'o.db'}", "--n-trials", "8")
    if child:
        r = _vibro(*args)
        _one_line_exit_2(r.returncode, r.stderr, "bundle.skops", "malformed", words)
    else:
        rc = main(list(args))
        _one_line_exit_2(rc, capsys.readouterr().err, "bundle.skops", "malformed", words)
    assert not (tmp_path / "o").exists()


# ----------------------------------------------------------------------------- bounded reads
@pytest.mark.parametrize("body, words", [
    (ALIAS_BOMB, "aliases"),
    ("sweep:\n  model: drill\n  model: pendulum\n", "duplicate key 'model'"),
])
def test_hostile_params_yaml_is_refused_quickly(tmp_path, body, words):
    p = tmp_path / "params.yaml"
    p.write_text(body)
    r = _vibro("sweep", "--params", str(p), "--out", str(tmp_path / "s"), timeout=60)
    _one_line_exit_2(r.returncode, r.stderr, str(p), words)
    assert not (tmp_path / "s").exists()


@pytest.mark.parametrize("body, words", [
    ("model: drill\nparameters: " + ALIAS_BOMB.replace("\n", "\n  ").rstrip() + "\n", "aliases"),
    ("model: drill\nmodel: pendulum\n", "duplicate key 'model'"),
])
def test_hostile_rig_file_is_refused(tmp_path, body, words):
    p = tmp_path / "rig.yaml"
    p.write_text(body)
    rc = main(["simulate", "--rig", str(p)])
    assert rc == 2


def test_rig_file_messages_name_file_line_and_cause(tmp_path, capsys):
    p = tmp_path / "rig.yaml"
    p.write_text("model: drill\nmodel: pendulum\n")
    assert main(["simulate", "--rig", str(p)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"rig file {p} line 2" in err and "duplicate key 'model'" in err


def test_params_from_a_stream_is_capped():
    r = _vibro("sweep", "--params", "/dev/zero", "--out", "/nonexistent/s", timeout=60)
    _one_line_exit_2(r.returncode, r.stderr, "/dev/zero", "MiB")


def test_text_reader_caps_size(tmp_path):
    from pipeline.core.bounded import read_text_capped
    from pipeline.core.errors import UserError

    p = tmp_path / "big.yaml"
    p.write_text("x" * 2049)
    assert read_text_capped(p, "f", limit=4096) == "x" * 2049
    with pytest.raises(UserError, match="more than"):
        read_text_capped(p, "f", limit=2048)


def test_local_scheduler_is_capped(tmp_path, capsys):
    from pipeline.core.dask_client import LOCAL_PER_CORE, local_workers

    assert local_workers("local:1") == 1
    cap = LOCAL_PER_CORE * (os.cpu_count() or 1)
    assert local_workers(f"local:{cap}") == cap
    rc = main(["sweep", "--out", str(tmp_path / "s"), "--scheduler", "local:100000"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and "local:100000" in err and f"[1, {cap}]" in err
    assert not (tmp_path / "s").exists()


# ----------------------------------------------------------------------------- chunks and labels
def _sweep_dir(root: Path) -> Path:
    """A one-chunk sweep written the way 'vibro sweep' writes it (chunk + sha256 sidecar + metadata)."""
    import numpy as np
    import pandas as pd

    from pipeline.core.integrity import write_with_checksum

    root.mkdir()
    n = 40
    rng = np.random.default_rng(0)
    df = pd.DataFrame({"point_id": np.arange(n), "frequency_hz": rng.uniform(100, 400, n),
                       "amplitude_n": rng.uniform(0, 3000, n), "rop_m_s": rng.uniform(1e-4, 3e-3, n),
                       "status": ["ok"] * n, "reason": [""] * n})
    write_with_checksum(root / "part-00000.parquet", lambda tmp: df.to_parquet(tmp))
    (root / "metadata.json").write_text(json.dumps({"model": "drill", "n_points": n, "n_chunks": 1,
                                                    "complete": True}))
    return root


def test_a_flipped_bit_in_a_chunk_is_named(tmp_path):
    from pipeline.core.errors import UserError
    from pipeline.datasets.store import load_dataset

    d = _sweep_dir(tmp_path / "sweep")
    assert len(load_dataset(d)) == 40
    part = d / "part-00000.parquet"
    data = bytearray(part.read_bytes())
    data[len(data) // 2] ^= 0x04
    part.write_bytes(bytes(data))
    with pytest.raises(UserError, match=r"part-00000.parquet: sha256 .* differs"):
        load_dataset(d)


def test_train_refuses_a_damaged_chunk(tmp_path, capsys):
    d = _sweep_dir(tmp_path / "sweep")
    part = d / "part-00000.parquet"
    data = bytearray(part.read_bytes())
    data[len(data) // 2] ^= 0x04
    part.write_bytes(bytes(data))
    rc = main(["train", str(d), "--out", str(tmp_path / "t"), "--no-mlflow", "--quiet"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and "part-00000.parquet" in err
    assert not (tmp_path / "t").exists()


def test_a_vibro_sweep_chunk_without_its_sidecar_is_refused(tmp_path):
    from pipeline.core.errors import UserError
    from pipeline.datasets.store import load_dataset

    d = _sweep_dir(tmp_path / "sweep")
    (d / "part-00000.parquet.sha256").unlink()
    with pytest.raises(UserError, match="no checksum file"):
        load_dataset(d)


@pytest.mark.parametrize("setting", ["M1=1e-30", "K1=1e300"])
def test_null_labels_come_with_failed_status_and_reason(setting):
    from sim import LABELS, simulate

    name, value = setting.split("=")
    lab = simulate("drill", preset="lab", **{name: float(value)}).labels
    nulls = [k for k in LABELS if lab[k] is None]
    assert nulls
    assert lab["status"] == "failed" and "not a number" in lab["reason"]


def test_normal_labels_keep_their_status():
    from sim import simulate

    lab = simulate("drill", preset="lab").labels
    assert lab["status"] in ("ok", "no_contact") and lab["reason"] == ""
    assert lab["rop_m_s"] is not None


@pytest.mark.parametrize("args, words", [
    (["--fs", "1"], "--fs 1 Hz"),
    (["--frequencies", "1e9"], "samples per cycle"),
])
def test_synth_refuses_what_diagnose_would_reject(tmp_path, capsys, args, words):
    rc = main(["synth", "--out", str(tmp_path / "d"), "--system", "drill", "--quiet", *args])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and words in err
    assert not (tmp_path / "d").exists() and not (tmp_path / "d.truth.json").exists()


# ----------------------------------------------------------------------------- tracking and workers
def test_mlflow_http_limits_default_small_but_user_wins(monkeypatch):
    from pipeline.tracking import runs

    for key in runs.HTTP_DEFAULTS:
        monkeypatch.delenv(key, raising=False)
    monkeypatch.setenv("MLFLOW_HTTP_REQUEST_TIMEOUT", "33")
    runs._quiet_mlflow()
    assert os.environ["MLFLOW_HTTP_REQUEST_TIMEOUT"] == "33"
    assert int(os.environ["MLFLOW_HTTP_REQUEST_MAX_RETRIES"]) <= 1


def test_unreachable_tracking_server_is_one_line_exit_2(tmp_path):
    env = {**os.environ, "MLFLOW_TRACKING_URI": "http://127.0.0.1:9", "MLFLOW_HTTP_REQUEST_TIMEOUT": "2"}
    env.pop("VIBRO_NO_MLFLOW", None)
    # sweep opens its run before simulating (a bad --scheduler is refused before either: not usable here)
    r = subprocess.run([sys.executable, "-m", "pipeline.cli", "sweep", "--out", str(tmp_path / "s"),
                        "--n-points", "1"], cwd=ROOT, env=env, capture_output=True, text=True, timeout=120)
    _one_line_exit_2(r.returncode, r.stderr, "http://127.0.0.1:9", "did not answer")


def _death_signal() -> int:
    """PR_GET_PDEATHSIG of the calling process."""
    import ctypes

    sig = ctypes.c_int(0)
    ctypes.CDLL(None).prctl(2, ctypes.byref(sig), 0, 0, 0)
    return sig.value


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="prctl is Linux-only")
def test_training_workers_die_with_their_parent():
    import signal

    from joblib import delayed

    from surrogate.selection import parallel

    got = parallel(2)(delayed(_death_signal)() for _ in range(2))
    assert got == [signal.SIGKILL, signal.SIGKILL]
    assert parallel(1)(delayed(_death_signal)() for _ in range(1)) == [0]    # never armed in this process


@pytest.mark.parametrize("model, preset", [("drill", "lab"), ("pendulum", None), ("indenter-metal", None)])
def test_a_point_past_its_work_limit_fails_with_the_reason(model, preset):
    """max_steps caps the accepted steps of a whole run (the DOPRI5 kernel and the drill's exact propagator)."""
    from sim import simulate

    lab = simulate(model, preset=preset, settings={"max_steps": 1000}).labels
    assert lab["status"] == "failed" and "work limit" in lab["reason"] and "max_steps" in lab["reason"]
    assert lab["n_steps"] <= 1100
    ok = simulate(model, preset=preset).labels       # the default limit leaves a normal point alone
    assert ok["status"] == "ok" and ok["n_steps"] < 5_000_000


@pytest.mark.parametrize("setting", ["K1=1e20", "frequency_hz=1e-6"])
def test_an_extreme_point_ends_failed_within_its_work_limit(setting):
    """Parameters far outside the model's range end as 'failed' with a reason instead of running for minutes."""
    from sim import simulate

    name, value = setting.split("=")
    lab = simulate("drill", preset="lab", **{name: float(value)}).labels
    assert lab["status"] == "failed" and lab["reason"]
