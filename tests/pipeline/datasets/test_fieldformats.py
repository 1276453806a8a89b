"""Rig files -> MODELS.md §7 (pipeline.datasets.fieldformats): every format round-trips known SI arrays written in a
lab's units, through the same checks; a wrong or missing unit, channel or property is one message naming the file
and the channel, with a did-you-mean."""
from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np
import pandas as pd
import pytest

from pipeline.core.units import G
from pipeline.datasets.fieldformats import FieldFormatError, import_runs, open_file, parse_mapping
from pipeline.datasets.measured import load_dataset, write_dataset

FS = 10_000.0                    # [Hz] DAQ rate
N = 400
F = 200.0                        # [Hz] forcing


def truth(k: int) -> dict[str, np.ndarray]:
    """Run ``k``'s SI signals (k = 0, 1)."""
    t = np.arange(N) / FS
    w = 2 * np.pi * F * t
    return {"t_s": t, "accel_m_s2": (30.0 + 5 * k) * np.sin(w) + 4.0 * np.cos(3 * w),
            "force_n": 1200.0 + (800.0 + 10 * k) * np.sin(w - 0.3), "disp_m": 1e-3 * np.sin(w - 1.2)}


# lab units of each signal: (unit, factor from SI to it)
LAB = {"t_s": ("ms", 1e3), "accel_m_s2": ("g", 1 / G), "force_n": ("kN", 1e-3), "disp_m": ("mm", 1e3)}
RUN_TABLE = {"frequency_hz": F, "amplitude_n": 800.0, "static_force_n": 1200.0, "gap_m": 0.0}


def lab(k: int, sig: str) -> np.ndarray:
    return truth(k)[sig] * LAB[sig][1]


def write_tdms(d: Path) -> dict:
    nptdms = pytest.importorskip("nptdms")
    objs = [nptdms.RootObject(properties={"Rig": "lab drill"})]
    for k in (0, 1):
        g = f"Run {k + 1:03d}"
        objs.append(nptdms.GroupObject(g, properties={"Forcing frequency": F, "Static load": 1.2}))
        for sig, name in (("accel_m_s2", "Accel"), ("force_n", "Load cell"), ("disp_m", "LVDT")):
            objs.append(nptdms.ChannelObject(g, name, lab(k, sig),
                                             properties={"unit_string": LAB[sig][0], "wf_increment": 1 / FS}))
    with nptdms.TdmsWriter(str(d / "rig.tdms")) as w:
        w.write_segment(objs)
    return {"file": "rig.tdms",
            "channels": {"accel_m_s2": "Accel", "force_n": "Load cell", "disp_m": {"channel": "LVDT", "unit": "mm"}},
            "run_defaults": {"system": "drill", "amplitude_n": "0.8 kN", "gap_m": 0,
                             "frequency_hz": {"property": "Forcing frequency"},
                             "static_force_n": {"property": "Static load", "unit": "kN"}},
            "runs": [{"run_id": f"r{k}", "group": f"Run {k + 1:03d}"} for k in (0, 1)]}


def write_hdf5(d: Path) -> dict:
    h5py = pytest.importorskip("h5py")
    with h5py.File(d / "rig.h5", "w") as f:
        f.attrs["rig"] = "lab drill"
        for k in (0, 1):
            g = f.create_group(f"runs/r{k}")
            g.attrs["frequency"] = F / 1e3
            g.attrs["F0"] = 800.0
            for sig, name in (("t_s", "time"), ("accel_m_s2", "accel"), ("force_n", "force"), ("disp_m", "disp")):
                ds = g.create_dataset(name, data=lab(k, sig))
                if sig != "disp_m":
                    ds.attrs["units"] = LAB[sig][0]
    return {"file": "rig.h5", "time": {"channel": "time"},
            "channels": {"accel_m_s2": "accel", "force_n": "force", "disp_m": {"channel": "disp", "unit": "mm"}},
            "run_defaults": {"system": "drill", "static_force_n": 1200, "gap_m": "0 mm",
                             "frequency_hz": {"attribute": "frequency", "unit": "kHz"},
                             "amplitude_n": {"attribute": "F0"}},
            "runs": [{"run_id": f"r{k}", "group": f"runs/r{k}"} for k in (0, 1)]}


def _mat_mapping(file: str) -> dict:
    return {"file": file, "time": {"rate_hz": {"variable": "fs", "unit": "kHz"}},
            "channels": {"accel_m_s2": {"channel": "accel", "unit": "g"}, "force_n": {"channel": "force", "unit": "kN"},
                         "disp_m": {"channel": "disp", "unit": "mm"}},
            "run_defaults": {"system": "drill", **RUN_TABLE},
            "runs": [{"run_id": f"r{k}", "group": f"run{k}"} for k in (0, 1)]}


def write_mat(d: Path) -> dict:
    from scipy import io

    io.savemat(d / "rig.mat", {"fs": FS / 1e3, **{f"run{k}": {s.split("_")[0]: lab(k, s)[:, None]
                                                              for s in ("accel_m_s2", "force_n", "disp_m")}
                                               for k in (0, 1)}})
    return _mat_mapping("rig.mat")


def write_mat73(d: Path) -> dict:
    """A MATLAB v7.3 file as MATLAB writes one: a 512-byte header, then HDF5 with column-major (1 x n) arrays."""
    h5py = pytest.importorskip("h5py")
    path = d / "rig73.mat"
    with h5py.File(path, "w", userblock_size=512) as f:
        f.create_dataset("fs", data=np.array([[FS / 1e3]])).attrs["MATLAB_class"] = np.bytes_("double")
        for k in (0, 1):
            g = f.create_group(f"run{k}")
            g.attrs["MATLAB_class"] = np.bytes_("struct")
            for s in ("accel_m_s2", "force_n", "disp_m"):
                g.create_dataset(s.split("_")[0], data=lab(k, s)[None, :]).attrs["MATLAB_class"] = np.bytes_("double")
            g.create_dataset("note", data=np.array([[ord(c) for c in "ok"]], dtype=np.uint16)).attrs[
                "MATLAB_class"] = np.bytes_("char")
    with open(path, "r+b") as fh:
        fh.write(b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Sat Nov 28 10:00:00 2026 HDF5 schema 1.00 .".ljust(116)
                 + b"\x00" * 8 + b"\x00\x02IM")
    return _mat_mapping("rig73.mat")


def write_csv(d: Path) -> dict:
    runs = []
    for k in (0, 1):
        pd.DataFrame({f"time [{LAB['t_s'][0]}]": lab(k, "t_s"), "accel [g]": lab(k, "accel_m_s2"),
                      "force [kN]": lab(k, "force_n"), "disp [mm]": lab(k, "disp_m")}).to_csv(
            d / f"run{k}.csv", index=False, float_format="%.17g")
        runs.append({"run_id": f"r{k}", "file": f"run{k}.csv"})
    return {"time": "time", "channels": {"accel_m_s2": "accel", "force_n": "force [kN]", "disp_m": "disp"},
            "run_defaults": {"system": "drill", **RUN_TABLE}, "runs": runs}


WRITERS: dict[str, Callable[[Path], dict]] = {"tdms": write_tdms, "hdf5": write_hdf5, "mat": write_mat,
                                              "mat73": write_mat73, "csv": write_csv}
"""Format -> writer of a two-run rig file in lab units (returns its mapping); every check below runs on each."""


def _import(d: Path, doc: dict):
    return import_runs(parse_mapping(doc, "map.yaml", d), open_file)


@pytest.mark.parametrize("fmt", WRITERS)
def test_round_trip_to_si(tmp_path, fmt):
    res = _import(tmp_path, WRITERS[fmt](tmp_path))
    ds = res.dataset
    assert list(ds.runs["run_id"]) == ["r0", "r1"]
    for k in (0, 1):
        s = ds.series[f"r{k}"]
        for sig, want in truth(k).items():
            np.testing.assert_allclose(s[sig].to_numpy(), want, rtol=1e-12, atol=1e-15, err_msg=f"{fmt} {sig}")
        row = ds.runs.iloc[k]
        for col, want in {**RUN_TABLE, "duration_s": N / FS}.items():
            assert float(row[col]) == pytest.approx(want, rel=1e-12), (fmt, col)
        assert res.runs[k].rate_hz == pytest.approx(FS)
    units = {c.signal: c.unit for c in res.runs[0].conversions}
    assert units == {s: LAB[s][0] for s in ("accel_m_s2", "force_n", "disp_m")}


@pytest.mark.parametrize("fmt", WRITERS)
def test_output_is_a_dataset_diagnose_reads(tmp_path, fmt):
    from pipeline.cli.diagnose import check_signals

    res = _import(tmp_path, WRITERS[fmt](tmp_path))
    out = write_dataset(res.dataset, tmp_path / "out")
    ds = load_dataset(out)                                   # the §7 validator vibro diagnose runs first
    check_signals(ds)
    assert ds.systems == ["drill"] and set(ds.series) == {"r0", "r1"}
    np.testing.assert_allclose(ds.series["r1"]["force_n"], truth(1)["force_n"], rtol=1e-9)


def _csv(d: Path, header: dict[str, np.ndarray]) -> None:
    pd.DataFrame(header).to_csv(d / "run.csv", index=False)


def _csv_map(**channels) -> dict:
    return {"file": "run.csv", "time": {"rate_hz": FS}, "channels": channels,
            "runs": [{"run_id": "r0", "system": "drill", **RUN_TABLE}]}


def _error(d: Path, doc: dict) -> str:
    with pytest.raises(FieldFormatError) as e:
        _import(d, doc)
    msg = str(e.value)
    assert "\n" not in msg
    return msg


def test_unknown_unit_names_file_and_channel(tmp_path):
    _csv(tmp_path, {"force [furlongs]": lab(0, "force_n")})
    msg = _error(tmp_path, _csv_map(force_n="force"))
    assert "run.csv" in msg and "'force'" in msg and "furlongs" in msg and "force units: N, kN" in msg


def test_close_unit_gets_did_you_mean(tmp_path):
    _csv(tmp_path, {"force [KN]": lab(0, "force_n")})
    assert "did you mean 'kN'?" in _error(tmp_path, _csv_map(force_n="force"))


def test_unit_of_the_wrong_quantity(tmp_path):
    _csv(tmp_path, {"force [mm]": lab(0, "force_n")})
    assert "'mm' is a length unit, not a force unit" in _error(tmp_path, _csv_map(force_n="force"))


def test_channel_without_unit_anywhere(tmp_path):
    _csv(tmp_path, {"accel": lab(0, "accel_m_s2")})
    msg = _error(tmp_path, _csv_map(accel_m_s2="accel"))
    assert "run.csv, channel 'accel' (accel_m_s2): no unit" in msg


def test_mapping_unit_must_agree_with_the_files(tmp_path):
    _csv(tmp_path, {"accel [g]": lab(0, "accel_m_s2")})
    msg = _error(tmp_path, _csv_map(accel_m_s2={"channel": "accel", "unit": "m/s2"}))
    assert "mapping says unit 'm/s2' but the file says 'g'" in msg
    # the same unit spelled the same way is fine
    res = _import(tmp_path, _csv_map(accel_m_s2={"channel": "accel", "unit": "g"}))
    np.testing.assert_allclose(res.dataset.series["r0"]["accel_m_s2"], truth(0)["accel_m_s2"], rtol=1e-12)


def test_unknown_channel_gets_did_you_mean(tmp_path):
    _csv(tmp_path, {"accel [g]": lab(0, "accel_m_s2")})
    msg = _error(tmp_path, _csv_map(accel_m_s2="acel"))
    assert "no channel 'acel'" in msg and "did you mean 'accel'?" in msg


def test_unknown_property_gets_did_you_mean(tmp_path):
    doc = write_tdms(tmp_path)
    doc["run_defaults"]["frequency_hz"] = {"property": "Forcing frequncy"}
    msg = _error(tmp_path, doc)
    assert "rig.tdms has no property 'Forcing frequncy'" in msg and "did you mean 'Forcing frequency'?" in msg


def test_tdms_without_wf_increment_needs_a_time(tmp_path):
    nptdms = pytest.importorskip("nptdms")
    with nptdms.TdmsWriter(str(tmp_path / "rig.tdms")) as w:
        w.write_segment([nptdms.ChannelObject("g", "Accel", lab(0, "accel_m_s2"), properties={"unit_string": "g"})])
    doc = {"file": "rig.tdms", "channels": {"accel_m_s2": "Accel"}, "runs": [{"run_id": "r0", "group": "g",
                                                                             "system": "drill", **RUN_TABLE}]}
    assert "channel 'g/Accel': no sample interval in the file" in _error(tmp_path, doc)
    doc["time"] = {"rate_hz": "10 kHz"}
    np.testing.assert_allclose(_import(tmp_path, doc).dataset.series["r0"]["t_s"], truth(0)["t_s"], rtol=1e-12)


def test_non_finite_sample_is_named(tmp_path):
    v = lab(0, "accel_m_s2")
    v[7] = np.nan
    _csv(tmp_path, {"accel [g]": v})
    assert "run.csv line 9, column 'accel [g]': empty" in _error(tmp_path, _csv_map(accel_m_s2="accel"))


def test_time_channel_start_shifts_and_drops(tmp_path):
    t = 5.0 + np.arange(N) / FS
    _csv(tmp_path, {"t [s]": t, "accel [g]": lab(0, "accel_m_s2")})
    doc = _csv_map(accel_m_s2="accel")
    doc["time"] = {"channel": "t", "start": 5.001}
    s = _import(tmp_path, doc).dataset.series["r0"]
    assert len(s) == N - 10
    assert s["t_s"].iloc[0] == pytest.approx(0.0, abs=1e-9)
    np.testing.assert_allclose(s["accel_m_s2"], truth(0)["accel_m_s2"][10:], rtol=1e-12)


@pytest.mark.parametrize(("doc", "expect"), [
    ({"channels": {"accel_m_s": "a"}}, "did you mean 'accel_m_s2'?"),
    ({"chanels": {}}, "unknown key 'chanels' (did you mean 'channels'?)"),
    ({"channels": {"accel_m_s2": {"channel": "a", "unit": "furlong"}}}, "accel_m_s2: unknown unit 'furlong'"),
    ({"time": {"rate_hz": "10 kHz", "channel": "t"}}, "not both"),
    ({"run_defaults": {"frequncy_hz": 3}}, "did you mean 'frequency_hz'?"),
    ({"run_defaults": {"gap_m": "2 kN"}}, "'kN' is a force unit, not a length unit"),
    ({"run_defaults": {"M1": "2 kg"}}, "give it as a plain number"),
])
def test_mapping_errors_name_the_key(tmp_path, doc, expect):
    base = {"file": "x.csv", "channels": {"accel_m_s2": "a"}, "runs": [{"run_id": "r0", "system": "drill"}]}
    with pytest.raises(FieldFormatError) as e:
        parse_mapping({**base, **doc}, "map.yaml", tmp_path)
    assert str(e.value).startswith("map.yaml") and expect in str(e.value)


def test_unknown_format_and_extension(tmp_path):
    (tmp_path / "log.dat").write_text("1\n")
    with pytest.raises(FieldFormatError, match="give 'format:'"):
        open_file(tmp_path / "log.dat")
    with pytest.raises(FieldFormatError, match="did you mean 'tdms'"):
        open_file(tmp_path / "log.dat", "tmds")


def test_summary_values_convert_and_validate(tmp_path):
    doc = write_csv(tmp_path)
    doc["runs"][0]["summary"] = {"rop_m_s": "1.2 mm/s", "peak_decel_g": "29.43 m/s2", "impacts_per_cycle": 1}
    ds = _import(tmp_path, doc).dataset
    assert ds.summary.loc["r0", "rop_m_s"] == pytest.approx(1.2e-3)
    assert ds.summary.loc["r0", "peak_decel_g"] == pytest.approx(3.0)
    back = load_dataset(write_dataset(ds, tmp_path / "out"))
    assert back.summary.index.tolist() == ["r0"] and back.summary.loc["r0", "impacts_per_cycle"] == 1


def test_extra_columns_and_text_properties_pass_through(tmp_path):
    doc = write_tdms(tmp_path)
    doc["run_defaults"].update({"preset": "lab", "operator_note": {"property": "Rig"}, "M1": 1.5})
    runs = _import(tmp_path, doc).dataset.runs
    assert list(runs["preset"]) == ["lab", "lab"] and list(runs["operator_note"]) == ["lab drill"] * 2
    assert list(runs["M1"]) == [1.5, 1.5]


def test_matrix_is_not_taken_for_a_signal(tmp_path):
    from scipy import io

    io.savemat(tmp_path / "rig.mat", {"fs": FS, "data": np.stack([lab(0, "accel_m_s2"), lab(0, "force_n")], axis=1)})
    doc = {"file": "rig.mat", "time": {"rate_hz": {"variable": "fs"}}, "channels": {"accel_m_s2": {"channel": "data",
           "unit": "g"}}, "runs": [{"run_id": "r0", "system": "drill", **RUN_TABLE}]}
    assert f"channel 'data': a {N} x 2 array, not one signal" in _error(tmp_path, doc)


def test_drill_rig_log_through_tdms_and_back(tmp_path):
    """The measured drill log (series runs) written as a LabVIEW VI would — one group per run, g / kN / mm,
    the run table as group properties in kN and ms — imports back to the same dataset."""
    nptdms = pytest.importorskip("nptdms")
    from pipeline.cli.diagnose import check_signals

    orig = load_dataset(Path(__file__).resolve().parents[3] / "measured" / "drill-rig")
    ids = [r for r in orig.series if "force_n" not in orig.series[r]][:1] + [r for r in orig.series
                                                                              if "force_n" in orig.series[r]][:3]
    lab_units = {"accel_m_s2": ("Accel", "g", 1 / G), "force_n": ("Load", "kN", 1e-3), "progression_m": ("Depth", "mm", 1e3)}
    objs, runs = [nptdms.RootObject(properties={"Rig": "lab drill"})], []
    for rid in ids:
        row = orig.runs.set_index("run_id").loc[rid]
        s = orig.series[rid]
        objs.append(nptdms.GroupObject(rid, properties={"Frequency": row["frequency_hz"], "F0": row["amplitude_n"] / 1e3,
                                                        "Fs": row["static_force_n"] / 1e3, "Preset": row["preset"],
                                                        "Start": row["record_start_s"] * 1e3}))
        step = float(s["t_s"].iloc[1])
        objs += [nptdms.ChannelObject(rid, name, s[sig].to_numpy() * k, properties={"unit_string": u, "wf_increment": step})
                 for sig, (name, u, k) in lab_units.items() if sig in s]
        runs.append({"run_id": rid, "group": rid, **({"channels": {"force_n": "Load"}} if "force_n" in s else {})})
    with nptdms.TdmsWriter(str(tmp_path / "rig.tdms")) as w:
        w.write_segment(objs)
    doc = {"file": "rig.tdms", "channels": {"accel_m_s2": "Accel", "progression_m": "Depth"},
           "run_defaults": {"system": "drill", "gap_m": 0, "frequency_hz": {"property": "Frequency"},
                            "amplitude_n": {"property": "F0", "unit": "kN"},
                            "static_force_n": {"property": "Fs", "unit": "kN"}, "preset": {"property": "Preset"},
                            "record_start_s": {"property": "Start", "unit": "ms"}},
           "runs": runs}
    back = load_dataset(write_dataset(_import(tmp_path, doc).dataset, tmp_path / "out"))
    check_signals(back)
    assert any("force_n" not in s for s in back.series.values()) and set(back.series) == set(ids)
    a, b = orig.runs.set_index("run_id").loc[ids], back.runs.set_index("run_id").loc[ids]
    for col in ("frequency_hz", "amplitude_n", "static_force_n", "record_start_s"):
        np.testing.assert_allclose(b[col].astype(float), a[col].astype(float), rtol=1e-12, err_msg=col)
    assert list(b["preset"]) == list(a["preset"])
    for rid in ids:
        assert list(back.series[rid].columns) == list(orig.series[rid].columns)
        np.testing.assert_allclose(back.series[rid].to_numpy(), orig.series[rid].to_numpy(), rtol=1e-9, atol=1e-15)


def test_summary_only_runs(tmp_path):
    doc = write_tdms(tmp_path)
    doc["runs"] += [{"run_id": "s0", "group": "Run 001", "channels": {}, "duration_s": 2.0,
                     "summary": {"rop_m_s": "0.6 mm/s", "peak_force_n": {"property": "Static load", "unit": "kN"}}},
                    {"run_id": "s1", "file": None, "channels": {}, "duration_s": "2000 ms", "frequency_hz": 150,
                     "static_force_n": 900, "summary": {"rop_m_s": "36 mm/min"}}]
    back = load_dataset(write_dataset(_import(tmp_path, doc).dataset, tmp_path / "out"))
    assert set(back.series) == {"r0", "r1"} and list(back.summary.index) == ["s0", "s1"]
    assert back.summary["rop_m_s"].tolist() == pytest.approx([6e-4, 6e-4])
    assert back.summary.loc["s0", "peak_force_n"] == pytest.approx(1200.0)
    assert back.runs.set_index("run_id").loc["s1", "duration_s"] == pytest.approx(2.0)
    doc["runs"][-1]["summary"]["rop_m_s"] = {"property": "ROP"}
    with pytest.raises(FieldFormatError, match="run 's1': no file"):
        parse_mapping(doc, "map.yaml", tmp_path)
    del doc["runs"][-1]["summary"]
    with pytest.raises(FieldFormatError, match=r"run 's1': no channels .* 'channels: \{\}' and a 'summary:' row"):
        parse_mapping(doc, "map.yaml", tmp_path)


@pytest.mark.parametrize("name", ["bad.tdms", "bad.h5", "bad.mat", "bad73.mat"])
def test_corrupt_file_is_named(tmp_path, name):
    head = b"MATLAB 7.3 MAT-file".ljust(128) if "73" in name else b""
    (tmp_path / name).write_bytes(head + b"garbage" * 40)
    with pytest.raises(FieldFormatError, match=rf"{name}: not a readable"):
        open_file(tmp_path / name)
