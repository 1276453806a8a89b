"""Surrogate bundles never run untrusted code: the manifest is checked before
anything is deserialised, the skops payload may hold only reviewed types, and a corrupt, foreign or
tampered bundle is a one-line user error (exit 2), also for `vibro report --surrogate`."""
from __future__ import annotations

import hashlib
import json
import pickle
from pathlib import Path

import pytest

from surrogate import load_bundle, train_bundle
from surrogate.bundle import MANIFEST, PAYLOAD, verify_bundle
from surrogate.errors import BundleError

from tests.surrogate.test_surrogate import FAST, RANGES, synthetic

pytestmark = pytest.mark.xdist_group("test_bundle_trust")   # one test worker builds the module's fixture



class Payload:
    """Would write a file if it were ever constructed from a bundle (it must never be)."""

    def __init__(self, flag: str = "") -> None:
        self.flag = flag

    def __setstate__(self, state):      # runs when skops (or pickle) rebuilds the object
        Path(state["flag"]).write_text("payload ran")

    def __reduce__(self):               # pickle: calls Path.write_text at load time
        return (Path.write_text, (Path(self.flag), "payload ran"))


@pytest.fixture(scope="module")
def bundle_dir(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("b") / "surrogate"
    train_bundle(synthetic(200), list(RANGES), RANGES, "drill", None, FAST).save(d)
    return d


def _copy(src: Path, dst: Path) -> Path:
    dst.mkdir()
    for f in src.iterdir():
        (dst / f.name).write_bytes(f.read_bytes())
    return dst


def _rehash(d: Path) -> None:
    """What an attacker who controls the folder can do: make the manifest match the files again."""
    man = json.loads((d / MANIFEST).read_text())
    for name, rec in man["files"].items():
        b = (d / name).read_bytes()
        rec.update(sha256=hashlib.sha256(b).hexdigest(), size=len(b))
    (d / MANIFEST).write_text(json.dumps(man))


def test_manifest_lists_every_file_with_its_hash(bundle_dir):
    man = verify_bundle(bundle_dir)
    assert man["kind"] == "vibro-surrogate-bundle" and man["format"] == 2 and man["payload"] == PAYLOAD
    assert set(man["files"]) == {PAYLOAD, "bundle.json", "report.json"}
    for name, rec in man["files"].items():
        b = (bundle_dir / name).read_bytes()
        assert rec == {"sha256": hashlib.sha256(b).hexdigest(), "size": len(b)}
    assert {"scikit-learn", "numpy", "skops"} <= set(man["versions"])
    assert not (bundle_dir / "bundle.joblib").exists()


def test_flipped_byte_in_payload_is_refused(bundle_dir, tmp_path):
    d = _copy(bundle_dir, tmp_path / "b")
    data = bytearray((d / PAYLOAD).read_bytes())
    data[len(data) // 2] ^= 0x01
    (d / PAYLOAD).write_bytes(bytes(data))
    with pytest.raises(BundleError, match=r"bundle.skops: sha256 differs from the bundle manifest"):
        load_bundle(d)


@pytest.mark.parametrize("damage, words", [
    (lambda d: (d / PAYLOAD).write_bytes((d / PAYLOAD).read_bytes()[:1000]), "truncated or replaced"),
    (lambda d: (d / PAYLOAD).unlink(), "missing"),
    (lambda d: (d / MANIFEST).write_text("{not json"), "unreadable bundle manifest"),
    (lambda d: (d / MANIFEST).write_text('{"kind": "other"}'), "not a vibro surrogate bundle manifest"),
    (lambda d: (d / MANIFEST).write_text(json.dumps({**json.loads((d / MANIFEST).read_text()), "format": 99})),
     "format 99"),
    (lambda d: (d / "bundle.json").write_text("{}"), "bundle.json"),
])
def test_damaged_bundle_is_a_one_line_user_error(bundle_dir, tmp_path, damage, words):
    d = _copy(bundle_dir, tmp_path / "b")
    damage(d)
    with pytest.raises(BundleError, match=words) as e:
        load_bundle(d)
    assert "\n" not in str(e.value)


def test_old_pickle_bundle_is_never_unpickled(tmp_path):
    """Issue 15: a crafted bundle.joblib ran its payload under optimise, verify and report."""
    d = tmp_path / "evil"
    d.mkdir()
    flag = tmp_path / "ran"
    (d / "bundle.joblib").write_bytes(pickle.dumps(Payload(str(flag))))
    with pytest.raises(BundleError, match="old-format surrogate bundle.*unpickling runs code"):
        load_bundle(d)
    assert not flag.exists()


def test_tampered_payload_with_matching_manifest_is_refused_by_type_check(bundle_dir, tmp_path):
    """A manifest catches damage, not an attacker (who rehashes): the skops type allow-list does."""
    import skops.io as sio

    d = _copy(bundle_dir, tmp_path / "b")
    flag = tmp_path / "ran"
    (d / PAYLOAD).write_bytes(sio.dumps({"bundle": Payload(str(flag))}))
    _rehash(d)
    verify_bundle(d)                                   # the hashes match now
    with pytest.raises(BundleError, match=r"holds type\(s\) a vibro bundle never contains "
                                        r"\(tests.surrogate.test_bundle_trust.Payload\)"):
        load_bundle(d)
    assert not flag.exists()


def test_not_a_skops_payload_is_refused(bundle_dir, tmp_path):
    d = _copy(bundle_dir, tmp_path / "b")
    (d / PAYLOAD).write_bytes(b"PK\x03\x04 garbage")
    _rehash(d)
    with pytest.raises(BundleError, match="bundle.skops: cannot be read"):
        load_bundle(d)


def test_cli_report_with_corrupt_surrogate_exits_2(bundle_dir, tmp_path, capsys, monkeypatch):
    """Issue 15: `report --surrogate DIR` with a corrupt bundle exited 0."""
    from pipeline.cli import main

    d = _copy(bundle_dir, tmp_path / "b")
    (d / PAYLOAD).write_bytes(b"x")
    monkeypatch.chdir(tmp_path)
    rc = main(["report", "--surrogate", str(d), "--out", str(tmp_path / "rep"), "--no-mlflow"])
    err = capsys.readouterr().err.strip()
    assert rc == 2
    assert len(err.splitlines()) == 1 and "bundle.skops" in err


def test_cli_optimise_with_pickle_bundle_exits_2_without_running_it(tmp_path, capsys):
    from pipeline.cli import main

    d = tmp_path / "evil"
    d.mkdir()
    flag = tmp_path / "ran"
    (d / "bundle.joblib").write_bytes(pickle.dumps(Payload(str(flag))))
    rc = main(["optimise", "--surrogate", str(d), "--out", str(tmp_path / "o"), "--no-mlflow", "--quiet",
               "--storage", f"sqlite:///{tmp_path / 'o.db'}"])
    assert rc == 2 and "old-format surrogate bundle" in capsys.readouterr().err
    assert not flag.exists()
