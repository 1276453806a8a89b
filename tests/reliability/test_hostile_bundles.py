"""Crafted surrogate bundles (a valid manifest, reviewed types only, but hostile stored values): `verify` and
`optimise --surrogate` exit 2 with one line naming the bundle and the value, before any prediction, write nothing,
and stay under a memory bound (the inflating bundle runs in a child under RLIMIT_AS).

``BUNDLE_CASES`` is counted by tests/reliability/corpus_summary.py."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from tests.reliability.test_bounded_and_trusted import _rehash
from tests.reliability.test_hostile_parsing import MEMORY_LIMIT, _limit_memory, one_error_line, snapshot

ROOT = Path(__file__).resolve().parents[2]




@pytest.fixture(scope="module")
def honest(tmp_path_factory) -> Path:
    """A small drill bundle with MLP classifier and regressor (weights to damage)."""
    from surrogate import train_bundle
    from tests.surrogate.test_surrogate import RANGES, synthetic

    cfg = {"regressors": ["mlp"], "classifiers": ["mlp"], "cv_folds": 2, "learning_curve": [1.0],
           "targets": ["rop_m_s"]}
    d = tmp_path_factory.mktemp("hb") / "surrogate"
    train_bundle(synthetic(120), list(RANGES), RANGES, "drill", None, cfg).save(d)
    return d


def _mlp(b):
    return b.regressors["rop_m_s"].estimator.regressor_


def _set(attr: str, value):
    return lambda b: setattr(b, attr, value)


def _wrong_weight(b) -> None:
    _mlp(b).coefs_[1] = np.zeros((7, 3))


def _nan_range(b) -> None:
    b.ranges["frequency_hz"] = (float("nan"), 400.0)
    b.scaler.ranges = b.ranges


def _inverted(b) -> None:
    b.ranges["amplitude_n"] = (3000.0, 0.0)
    b.scaler.ranges = b.ranges


def _short_inputs(b) -> None:
    b.inputs = b.inputs[:1]
    b.ranges = {n: b.ranges[n] for n in b.inputs}
    b.scaler.inputs, b.scaler.ranges = b.inputs, b.ranges


def _string_rtol(b) -> None:
    b.settings = {"rtol": "1e-8"}


def _nan_weight(b) -> None:
    _mlp(b).coefs_[0][0, 0] = np.nan


def _negative_q(b) -> None:
    b.regressors["rop_m_s"].interval.q = -1.0


BUNDLE_CASES = [
    ("empty-ranges", _set("ranges", {}), "'ranges' must give one range per input"),
    ("short-inputs", _short_inputs, "fitted on 2 inputs, the bundle lists 1"),
    ("mlp-weight-wrong-shape", _wrong_weight, "MLP layer 1 weight has shape (7, 3)"),
    ("string-rtol", _string_rtol, "setting 'rtol' must be a finite number"),
    ("nan-range", _nan_range, "trained range of 'frequency_hz' is not two finite numbers"),
    ("inverted-range", _inverted, "trained range of 'amplitude_n' is inverted"),
    ("nan-weight", _nan_weight, "non-finite weights"),
    ("negative-interval", _negative_q, "interval half-width q"),
    ("fixed-not-a-number", _set("fixed", {"static_force_n": "lots"}), "fixed value 'static_force_n'"),
]
COMMANDS = {
    "verify": "verify {t}/pts.csv --surrogate {t}/evil --out {t}/o --no-mlflow --quiet",
    "optimise": "optimise --surrogate {t}/evil --out {t}/o --no-mlflow --quiet --n-trials 4 "
                "--storage sqlite:///{t}/o.db",
}


def _craft(honest: Path, d: Path, damage) -> Path:
    import skops.io as sio

    from surrogate import load_bundle

    d.mkdir()
    for f in honest.iterdir():
        (d / f.name).write_bytes(f.read_bytes())
    b = load_bundle(d)
    damage(b)
    (d / "bundle.skops").write_bytes(sio.dumps(b))
    _rehash(d)
    return d


@pytest.mark.parametrize("command", sorted(COMMANDS))
@pytest.mark.parametrize("case", BUNDLE_CASES, ids=[c[0] for c in BUNDLE_CASES])
def test_crafted_bundle_is_refused_before_predicting(case, command, honest, tmp_path, capsys, monkeypatch):
    from pipeline.cli import main

    name, damage, words = case
    monkeypatch.setenv("VIBRO_NO_MLFLOW", "1")
    monkeypatch.chdir(tmp_path)
    _craft(honest, tmp_path / "evil", damage)
    (tmp_path / "pts.csv").write_text("frequency_hz,amplitude_n\n200,1500\n")
    before = snapshot(tmp_path)
    rc = main(COMMANDS[command].format(t=tmp_path).split())
    one_error_line(rc, capsys.readouterr().err, ["bundle.skops", "malformed bundle", words])
    assert snapshot(tmp_path) == before


def test_honest_bundle_passes_the_validator(honest):
    from surrogate import load_bundle

    b = load_bundle(honest)          # every check, the probe prediction included
    assert b.inputs == ["frequency_hz", "amplitude_n"]


def _inflating(honest: Path, d: Path, n_bytes: int) -> Path:
    """``honest`` with one more archive member of ``n_bytes`` zeros (deflated to a few hundred kB)."""
    d.mkdir()
    for f in honest.iterdir():
        (d / f.name).write_bytes(f.read_bytes())
    with zipfile.ZipFile(d / "bundle.skops", "a", compression=zipfile.ZIP_DEFLATED, compresslevel=1) as z:
        with z.open("0123456789.npy", "w", force_zip64=True) as fh:
            chunk = bytes(2**24)
            for _ in range(n_bytes // len(chunk)):
                fh.write(chunk)
    _rehash(d)
    return d


def test_inflating_bundle_is_refused_before_allocating(honest, tmp_path):
    """A small payload whose members would inflate past surrogate.bundle_check.MAX_INFLATED_BYTES."""
    from surrogate.bundle_check import MAX_INFLATED_BYTES

    d = _inflating(honest, tmp_path / "evil", MAX_INFLATED_BYTES + 2**24)
    assert (d / "bundle.skops").stat().st_size < 8 * 2**20
    (tmp_path / "pts.csv").write_text("frequency_hz,amplitude_n\n200,1500\n")
    before = snapshot(tmp_path)
    env = {**os.environ, "VIBRO_NO_MLFLOW": "1"}
    r = subprocess.run([sys.executable, "-m", "pipeline.cli", "verify", str(tmp_path / "pts.csv"), "--surrogate",
                        str(d), "--out", str(tmp_path / "o"), "--no-mlflow"], cwd=tmp_path, env=env,
                       capture_output=True, text=True, timeout=120, preexec_fn=_limit_memory)
    one_error_line(r.returncode, r.stderr, ["bundle.skops", "MiB once inflated"])
    assert snapshot(tmp_path) == before
    assert MEMORY_LIMIT < 4 * 2**30


def test_oversized_bundle_file_is_refused_before_hashing(honest, tmp_path, capsys):
    """A listed file larger than bundle.MAX_FILE_BYTES (here sparse: no disk used) is refused by its size."""
    from pipeline.cli import main
    from surrogate.bundle import MAX_FILE_BYTES

    d = tmp_path / "evil"
    d.mkdir()
    for f in honest.iterdir():
        (d / f.name).write_bytes(f.read_bytes())
    os.truncate(d / "report.json", MAX_FILE_BYTES + 1)
    man = json.loads((d / "manifest.json").read_text())
    man["files"]["report.json"]["size"] = MAX_FILE_BYTES + 1      # the hash is never reached
    (d / "manifest.json").write_text(json.dumps(man))
    (tmp_path / "pts.csv").write_text("frequency_hz,amplitude_n\n200,1500\n")
    before = snapshot(tmp_path)
    rc = main(["verify", str(tmp_path / "pts.csv"), "--surrogate", str(d), "--out", str(tmp_path / "o"), "--no-mlflow"])
    one_error_line(rc, capsys.readouterr().err, ["report.json", "MiB a bundle file may hold"])
    assert snapshot(tmp_path) == before
