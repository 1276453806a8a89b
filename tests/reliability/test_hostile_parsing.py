"""The hostile-input corpus of storages, numbers, scheduler addresses and bundles: each case exits 2 with one line
naming the culprit, changes no file the user has (sha256 of every file under the test folder before and after)
and creates none outside ``--out``; the cases that could ask for memory run in a child under RLIMIT_AS.

``CASES`` run in this process; ``BOUNDED`` in a child process under MEMORY_LIMIT.  tests/reliability/corpus_summary.py
counts both.
"""
from __future__ import annotations

import hashlib
import http.server
import json
import os
import resource
import socket
import sqlite3
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from pipeline.cli import main

ROOT = Path(__file__).resolve().parents[2]
MEMORY_LIMIT = 3 * 2**30
"""Address-space limit of a BOUNDED case's child process [bytes]."""
NO_ML = "--no-mlflow"
OPT = "optimise --simulator --n-trials 2 --out {t}/o " + NO_ML
JOURNAL = OPT + " --storage journal:///{t}/j.log"
NOT_JOURNAL = ["j.log", "not an optuna journal"]


# ----------------------------------------------------------------------------------- file set-ups
def _dataset(root: Path, extra_col: str = "", extra_val: str = "") -> Path:
    """A small measured dataset (MODELS.md §7, summary only), with one extra runs.csv column."""
    root.mkdir(parents=True, exist_ok=True)
    head = "run_id,system,frequency_hz,amplitude_n,static_force_n,gap_m,duration_s,pressure_bar"
    rows = [f"m{f},indenter-metal,{f},{300 + 5 * f},198.9512,0.001,0.05,1.0" for f in (40, 60, 80)]
    if extra_col in head.split(","):
        i = head.split(",").index(extra_col)
        rows = [",".join(extra_val if j == i else c for j, c in enumerate(r.split(","))) for r in rows[:1]] + rows[1:]
    elif extra_col:
        head += "," + extra_col
        rows = [r + "," + extra_val for r in rows]
    (root / "runs.csv").write_text(head + "\n" + "\n".join(rows) + "\n")
    (root / "summary.csv").write_text("run_id,peak_decel_g,impacts_per_cycle\n"
                                      + "".join(f"m{f},15.7,6\n" for f in (40, 60, 80)))
    return root


def _other_app_db(path: Path) -> None:
    con = sqlite3.connect(path)
    con.execute("CREATE TABLE notes (id INTEGER PRIMARY KEY, body TEXT)")
    con.execute("INSERT INTO notes (body) VALUES ('my thesis notes')")
    con.commit()
    con.close()


def _fifo(path: Path) -> None:
    os.mkfifo(path)


def _drill_points(t: Path) -> None:
    (t / "pts.csv").write_text("frequency_hz,amplitude_n,static_force_n\n150,1500,200\n200,1800,200\n")


def _pendulum_rig(t: Path) -> None:
    (t / "pendulum-rig.yaml").write_text("model: pendulum\n")


def _reports(t: Path) -> None:
    for name in ("unc", "cor"):
        (t / name).mkdir()
        (t / name / "report.json").write_text(json.dumps(
            {"tried": {"model": "drill"}, "inputs": [], "recommendation": {"params": {"frequency_hz": 150.0}}}))
    _pendulum_rig(t)


def _params(body: str):
    return lambda t: (t / "p.yaml").write_text(body)


def _rig(body: str):
    return lambda t: (t / "rig.yaml").write_text(body)


BIG_401 = "9" * 401
BIG_5001 = "7" * 5001
SETUPS = {
    "journal_json": lambda t: (t / "j.log").write_text('{"a": 1}\n'),
    "journal_text": lambda t: (t / "j.log").write_text("my notes, one line\n"),
    "journal_text_no_newline": lambda t: (t / "j.log").write_text("my notes without a final newline"),
    "journal_is_sqlite": lambda t: _other_app_db(t / "j.log"),
    "journal_dir": lambda t: (t / "jdir").mkdir(),
    "journal_fifo": lambda t: _fifo(t / "j.fifo"),
    "sqlite_other_app": lambda t: _other_app_db(t / "app.db"),
    "sqlite_text": lambda t: (t / "notes.db").write_text("not a database\n"),
    "sqlite_dir": lambda t: (t / "dbdir").mkdir(),
    "sqlite_fifo": lambda t: _fifo(t / "db.fifo"),
    "params_int_401": _params(f"sweep:\n  n_points: {BIG_401}\n"),
    "params_int_5001": _params(f"sweep:\n  seed: {BIG_5001}\n"),
    "params_float_overflow": _params("sweep:\n  settings: {rtol: 1e400}\n"),
    "params_quoted_1e5": _params('sweep:\n  n_points: "1e5"\n'),
    "params_quoted_1_000": _params("sweep:\n  n_points: '1_000'\n"),
    "params_opt_quoted": _params('optimise:\n  n_trials: "12"\n'),
    "params_opt_range_quoted": _params('optimise:\n  ranges: {frequency_hz: ["100", 300]}\n'),
    "rig_int_401": _rig(f"model: drill\nparameters: {{K1: {BIG_401}}}\n"),
    "rig_int_5001": _rig(f"model: drill\nparameters: {{K1: {BIG_5001}}}\n"),
    "rig_float_overflow": _rig("model: drill\nparameters: {K1: 1.0e400}\n"),
    "rig_quoted": _rig('model: drill\nparameters: {K1: "5.2e8"}\n'),
    "rig_quoted_underscore": _rig("model: drill\nparameters: {K1: '520_000_000'}\n"),
    "rig_fc_tiny": _rig("model: drill\neffects: {sensor_lowpass: {fc: 1.0e-12}}\n"),
    "rig_mode_hz_only": _rig("model: drill\ndiscrepancy: {load_path_mode_hz: 300.0}\n"),
    "rig_mode_zeta_only": _rig("model: drill\ndiscrepancy: {load_path_mode_zeta: 0.05}\n"),
    "dataset_record_start_1e12": lambda t: _dataset(t / "ds", "record_start_s", "1e12"),
    "dataset_k1_1e300": lambda t: _dataset(t / "ds", "k1", "1e300"),
    "dataset_k1_underscore": lambda t: _dataset(t / "ds", "k1", "1_000"),
    "dataset_gap_1e300": lambda t: _dataset(t / "ds", "gap_m", "1e300"),
    "dataset": lambda t: _dataset(t / "ds"),
    "dataset_summary_fifo": lambda t: (_dataset(t / "ds"), (t / "ds" / "summary.csv").unlink(),
                                       _fifo(t / "ds" / "summary.csv")),
    "drill_points_pendulum_rig": lambda t: (_drill_points(t), _pendulum_rig(t)),
    "reports_pendulum_rig": _reports,
    "reports_big_int_rig": lambda t: (_reports(t), _rig(f"model: drill\nparameters: {{K1: {BIG_401}}}\n")(t)),
    "points_big_int_rig": lambda t: (_drill_points(t), _rig(f"model: drill\nparameters: {{K1: {BIG_401}}}\n")(t)),
}

# (id, argv with {t} = the test's folder, set-up or None, fragments the one error line must contain)
CASES = [
    # --- storages never write into what is not theirs ------------------------------------------------------
    ("journal-holding-json", JOURNAL, "journal_json", NOT_JOURNAL),
    ("journal-holding-text", JOURNAL, "journal_text", NOT_JOURNAL),
    ("journal-text-no-newline", JOURNAL, "journal_text_no_newline", NOT_JOURNAL),
    ("journal-is-sqlite-db", JOURNAL, "journal_is_sqlite", NOT_JOURNAL),
    ("journal-dev-null", OPT + " --storage journal:///dev/null", None, ["/dev/null", "device"]),
    ("journal-is-folder", OPT + " --storage journal:///{t}/jdir", "journal_dir", ["jdir", "folder"]),
    ("journal-is-fifo", OPT + " --storage journal:///{t}/j.fifo", "journal_fifo", ["j.fifo", "pipe"]),
    ("sqlite-other-app", OPT + " --storage sqlite:///{t}/app.db", "sqlite_other_app",
     ["app.db", "another application's database", "notes"]),
    ("sqlite-text-file", OPT + " --storage sqlite:///{t}/notes.db", "sqlite_text", ["notes.db", "not an SQLite"]),
    ("sqlite-dev-null", OPT + " --storage sqlite:////dev/null", None, ["/dev/null", "device"]),
    ("sqlite-is-folder", OPT + " --storage sqlite:///{t}/dbdir", "sqlite_dir", ["dbdir", "folder"]),
    ("sqlite-is-fifo", OPT + " --storage sqlite:///{t}/db.fifo", "sqlite_fifo", ["db.fifo", "pipe"]),
    ("sqlite-empty-path", OPT + " --storage sqlite:///", None, ["sqlite:///", "name the database file"]),
    # --- one number parser: YAML, CSV, flags ---------------------------------------------------------------
    ("params-int-401-digits", "sweep --params {t}/p.yaml --out {t}/o --dry-run", "params_int_401",
     ["p.yaml", "line 2", "401 digits"]),
    ("params-int-5001-digits", "sweep --params {t}/p.yaml --out {t}/o --dry-run", "params_int_5001",
     ["p.yaml", "5001 digits"]),
    ("params-float-1e400", "sweep --params {t}/p.yaml --out {t}/o --dry-run", "params_float_overflow",
     ["p.yaml", "rtol", "1e400"]),
    ("params-quoted-1e5", "sweep --params {t}/p.yaml --out {t}/o --dry-run", "params_quoted_1e5",
     ["n_points", "'1e5' is quoted text"]),
    ("params-quoted-1_000", "sweep --params {t}/p.yaml --out {t}/o --dry-run", "params_quoted_1_000",
     ["n_points", "'1_000' is quoted text"]),
    ("params-optimise-quoted", "optimise --simulator --params {t}/p.yaml --out {t}/o " + NO_ML, "params_opt_quoted",
     ["n_trials", "quoted text"]),
    ("params-optimise-range-quoted", "optimise --simulator --params {t}/p.yaml --out {t}/o " + NO_ML,
     "params_opt_range_quoted", ["frequency_hz", "quoted text"]),
    ("rig-int-401-digits", "simulate --rig {t}/rig.yaml", "rig_int_401", ["rig.yaml", "401 digits"]),
    ("rig-int-5001-digits-sweep", "sweep --rig {t}/rig.yaml --out {t}/o --dry-run", "rig_int_5001",
     ["rig.yaml", "5001 digits"]),
    ("rig-int-401-map", "map --rig {t}/rig.yaml --x frequency_hz --nx 3", "rig_int_401", ["rig.yaml", "401 digits"]),
    ("rig-int-401-optimise", OPT + " --rig {t}/rig.yaml", "rig_int_401", ["rig.yaml", "401 digits"]),
    ("rig-float-1e400", "simulate --rig {t}/rig.yaml", "rig_float_overflow", ["rig.yaml", "1.0e400", "out of range"]),
    ("rig-int-401-verify", "verify {t}/pts.csv --rig {t}/rig.yaml --out {t}/o " + NO_ML, "points_big_int_rig",
     ["rig.yaml", "401 digits"]),
    ("rig-int-401-compare", "compare --uncorrected {t}/unc --corrected {t}/cor --rig {t}/rig.yaml --out {t}/o " + NO_ML,
     "reports_big_int_rig", ["rig.yaml", "401 digits"]),
    ("rig-quoted-number", "simulate --rig {t}/rig.yaml", "rig_quoted", ["rig.yaml", "K1", "quoted text"]),
    ("rig-quoted-underscore", "simulate --rig {t}/rig.yaml", "rig_quoted_underscore", ["K1", "quoted text"]),
    ("set-underscore-number", "simulate drill --set K1=1_000", None, ["--set K1", "'1_000' is not a number"]),
    ("set-hex-number", "simulate drill --set K1=0x10", None, ["--set K1", "not a number"]),
    ("vary-underscore-number", "optimise --simulator --vary frequency_hz=1_00:300 --out {t}/o " + NO_ML, None,
     ["--vary frequency_hz", "not a number"]),
    ("runs-record-start-1e12", "diagnose {t}/ds --out {t}/o " + NO_ML, "dataset_record_start_1e12",
     ["runs.csv line 2", "record_start_s", "1e+12"]),
    ("runs-k1-1e300", "diagnose {t}/ds --out {t}/o " + NO_ML, "dataset_k1_1e300",
     ["runs.csv line 2", "'k1'", "1e+300"]),
    ("runs-k1-underscore", "diagnose {t}/ds --out {t}/o " + NO_ML, "dataset_k1_underscore",
     ["runs.csv line 2", "'k1'", "not a number"]),
    ("runs-gap-1e300", "diagnose {t}/ds --out {t}/o " + NO_ML, "dataset_gap_1e300", ["runs.csv line 2", "gap_m"]),
    ("runs-summary-is-fifo", "diagnose {t}/ds --out {t}/o " + NO_ML, "dataset_summary_fifo",
     ["summary.csv", "not a regular file"]),
    # --- one scheduler-address parser ------------------------------------------------------------------------
    ("diagnose-scheduler-garbage", "diagnose {t}/ds --out {t}/o --scheduler garbage " + NO_ML, "dataset",
     ["--scheduler garbage"]),
    ("diagnose-scheduler-ipv6-open", "diagnose {t}/ds --out {t}/o --scheduler tcp://[::1 " + NO_ML, "dataset",
     ["--scheduler tcp://[::1", "IPv6"]),
    ("diagnose-scheduler-port-99999", "diagnose {t}/ds --out {t}/o --scheduler tcp://127.0.0.1:99999 " + NO_ML,
     "dataset", ["tcp://127.0.0.1:99999", "1..65535"]),
    ("sweep-scheduler-garbage", "sweep --out {t}/o --n-points 2 --scheduler garbage " + NO_ML, None,
     ["--scheduler garbage"]),
    ("sweep-scheduler-ipv6-open", "sweep --out {t}/o --n-points 2 --scheduler tcp://[::1 " + NO_ML, None,
     ["tcp://[::1"]),
    ("sweep-scheduler-port-99999", "sweep --out {t}/o --n-points 2 --scheduler tcp://127.0.0.1:99999 " + NO_ML, None,
     ["1..65535"]),
    ("sweep-scheduler-unknown-protocol", "sweep --out {t}/o --n-points 2 --scheduler http://127.0.0.1:80 " + NO_ML,
     None, ["http://", "unknown protocol"]),
    ("sweep-scheduler-nobody-listens", "sweep --out {t}/o --n-points 2 --scheduler tcp://127.0.0.1:{closed} " + NO_ML,
     None, ["cannot reach"]),
    ("sweep-scheduler-http-port", "sweep --out {t}/o --n-points 2 --scheduler tcp://127.0.0.1:{http} " + NO_ML, None,
     ["not a Dask scheduler"]),
    ("diagnose-scheduler-http-port", "diagnose {t}/ds --out {t}/o --scheduler tcp://127.0.0.1:{http} " + NO_ML,
     "dataset", ["not a Dask scheduler"]),
    # --- the other parsing cases ---------------------------------------------------------------------
    ("synth-outside-fr-1e300", "synth --out {t}/o --outside mount_resonance --outside-param fr_hz=1e300", None,
     ["--outside-param fr_hz=1e+300"]),
    ("synth-outside-fr-0", "synth --out {t}/o --outside mount_resonance --outside-param fr_hz=0", None,
     ["--outside-param fr_hz=0"]),
    ("synth-outside-unknown-name", "synth --out {t}/o --outside mount_resonance --outside-param q=3", None,
     ["--outside-param q", "fr_hz, zeta"]),
    ("synth-outside-param-without-outside", "synth --out {t}/o --outside-param zeta=0.1", None,
     ["--outside-param zeta", "--outside"]),
    ("synth-outside-zeta-1e300", "synth --out {t}/o --outside mount_resonance --outside-param zeta=1e300", None,
     ["zeta=1e+300", "damping ratio"]),
    ("synth-outside-zeta-negative", "synth --out {t}/o --outside mount_resonance --outside-param zeta=-1", None,
     ["zeta=-1", "damping ratio"]),
    ("synth-record-start-1e12", "synth --out {t}/o --record-start 1e12", None, ["--record-start 1e+12"]),
    ("optimise-objectives-unknown", OPT + " --objectives rop_m_s,os.system", None, ["os.system", "not a label"]),
    ("optimise-objectives-unknown-pareto", OPT + " --objective pareto --objectives rop_m_s,os.system", None,
     ["os.system", "not a label"]),
    ("optimise-objectives-without-pareto", OPT + " --objectives rop_m_s,power_w", None,
     ["--objectives", "--objective pareto"]),
    ("optimise-vary-absurd-range", "optimise --simulator --vary frequency_hz=1e-300:1e300 --out {t}/o " + NO_ML, None,
     ["frequency_hz", "not a physical range"]),
    ("verify-drill-points-pendulum-rig", "verify {t}/pts.csv --rig {t}/pendulum-rig.yaml --out {t}/o " + NO_ML,
     "drill_points_pendulum_rig", ["pts.csv", "amplitude_n", "pendulum", "another model"]),
    ("compare-pendulum-rig-drill-reports",
     "compare --uncorrected {t}/unc --corrected {t}/cor --rig {t}/pendulum-rig.yaml --out {t}/o " + NO_ML,
     "reports_pendulum_rig", ["pendulum", "drill", "optimised model"]),
    ("rig-mode-hz-without-ratio", "simulate --rig {t}/rig.yaml", "rig_mode_hz_only",
     ["load_path_mode_hz without load_path_mode_ratio"]),
    ("rig-mode-zeta-without-ratio", "simulate --rig {t}/rig.yaml", "rig_mode_zeta_only",
     ["load_path_mode_zeta without load_path_mode_ratio"]),
    ("rig-sensor-lowpass-fc-1e-12", "simulate --rig {t}/rig.yaml", "rig_fc_tiny",
     ["rig.yaml", "'fc'", "0 (off) or >= 1"]),
    ("set-sensor-lowpass-fc-1e-12", "simulate drill --set fc=1e-12", None, ["'fc'", "0 (off) or >= 1"]),
    ("set-mode-hz-without-ratio", "simulate drill --set load_path_mode_hz=300", None,
     ["load_path_mode_hz without load_path_mode_ratio"]),
]

# cases that could ask for memory or recursion: run in a child process under MEMORY_LIMIT
BOUNDED = [
    ("params-nested-50000", "sweep --params {t}/p.yaml --out {t}/o --dry-run",
     _params("sweep: " + "[" * 50_000 + "]" * 50_000 + "\n"), ["p.yaml", "nested more than"]),
    ("rig-nested-50000", "simulate --rig {t}/rig.yaml", _rig("model: drill\nparameters: " + "[" * 50_000 + "\n"),
     ["rig.yaml", "nested more than"]),
    ("params-int-5001-digits-child", "sweep --params {t}/p.yaml --out {t}/o --dry-run",
     _params(f"sweep:\n  n_points: {BIG_5001}\n"), ["p.yaml", "5001 digits"]),
]


# ----------------------------------------------------------------------------------- the checks
def snapshot(root: Path) -> dict[str, str]:
    """Relative path -> sha256 of every file under ``root`` ('<dir>' for folders, '<fifo>' for pipes)."""
    import stat

    out = {}
    for p in sorted(root.rglob("*")):
        mode = p.lstat().st_mode
        out[str(p.relative_to(root))] = (hashlib.sha256(p.read_bytes()).hexdigest() if stat.S_ISREG(mode)
                                         else "<dir>" if stat.S_ISDIR(mode) else "<fifo>")
    return out


def one_error_line(rc: int, err: str, fragments: list[str]) -> None:
    lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith("usage:") and not ln.startswith(" ")]
    assert rc == 2, err
    assert len(lines) == 1 and "error" in lines[0] and "internal error" not in lines[0], err
    for f in fragments:
        assert f in lines[0], (f, lines[0])


@pytest.fixture(scope="module")
def ports():
    """{'http': a port where an HTTP server answers, 'closed': a port where nothing listens}."""
    class Quiet(http.server.BaseHTTPRequestHandler):
        def log_message(self, *a):
            pass

    srv = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Quiet)
    threading.Thread(target=srv.serve_forever, daemon=True).start()
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    closed = s.getsockname()[1]
    s.close()
    yield {"http": srv.server_address[1], "closed": closed}
    srv.shutdown()


@pytest.fixture(autouse=True)
def _no_mlflow(monkeypatch):
    monkeypatch.setenv("VIBRO_NO_MLFLOW", "1")


DEV_LEFTOVERS = ("/dev/null.lock", "/dev/null.workers", "/dev/null-journal", "/dev/null-wal")


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_hostile_input(case, tmp_path, capsys, monkeypatch, ports):
    name, argv, setup, fragments = case
    monkeypatch.chdir(tmp_path)
    if setup:
        SETUPS[setup](tmp_path)
    before = snapshot(tmp_path)
    dev_before = {p for p in DEV_LEFTOVERS if os.path.lexists(p)}
    try:
        rc = main(argv.format(t=tmp_path, **ports).split())
    except SystemExit as e:
        rc = e.code
    one_error_line(rc, capsys.readouterr().err, fragments)
    assert snapshot(tmp_path) == before, "a file changed or was left behind"
    assert {p for p in DEV_LEFTOVERS if os.path.lexists(p)} == dev_before, "a file was created in /dev"


def _limit_memory() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))


@pytest.mark.parametrize("case", BOUNDED, ids=[c[0] for c in BOUNDED])
def test_hostile_input_in_bounded_memory(case, tmp_path):
    name, argv, setup, fragments = case
    setup(tmp_path)
    before = snapshot(tmp_path)
    env = {**os.environ, "VIBRO_NO_MLFLOW": "1"}
    r = subprocess.run([sys.executable, "-m", "pipeline.cli", *argv.format(t=tmp_path).split()], cwd=tmp_path,
                       env=env, capture_output=True, text=True, timeout=120, preexec_fn=_limit_memory)
    one_error_line(r.returncode, r.stderr, fragments)
    assert snapshot(tmp_path) == before


def test_an_optuna_journal_and_database_are_accepted(tmp_path):
    """The checks refuse only what is not optuna's: a journal and a database optuna wrote pass them."""
    import optuna

    from pipeline.optimise.storages import check_storage_target

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    log, db = tmp_path / "s.log", tmp_path / "s.db"
    optuna.create_study(storage=optuna.storages.JournalStorage(optuna.storages.journal.JournalFileBackend(str(log))),
                        study_name="x")
    optuna.create_study(storage=f"sqlite:///{db}", study_name="x")
    for url in (f"journal:///{log}", f"sqlite:///{db}", f"journal:///{tmp_path}/new.log", f"sqlite:///{tmp_path}/n.db",
                "sqlite:///:memory:"):
        check_storage_target(url)
    (tmp_path / "empty.db").write_bytes(b"")
    check_storage_target(f"sqlite:///{tmp_path}/empty.db")


@pytest.mark.parametrize("address, expected", [
    ("local:1", "local:1"), ("tcp://10.0.0.5:8786", "tcp://10.0.0.5:8786"), ("10.0.0.5:8786", "tcp://10.0.0.5:8786"),
    ("tcp://[::1]:8786", "tcp://[::1]:8786"), ("tls://sched.example.org:8786", "tls://sched.example.org:8786"),
])
def test_scheduler_addresses_that_name_a_scheduler(address, expected):
    from pipeline.core.dask_client import check_address

    assert check_address(address) == expected


def test_number_parser_types():
    from pipeline.core.errors import UserError
    from pipeline.core.numbers import QuotedNumber, number

    assert number("1e5", "x") == 1e5 and number(" -2.5 ", "x") == -2.5 and number(7, "x", integer=True) == 7
    assert isinstance(number("300", "x", integer=True), int)
    for bad in ("1_000", "0x10", "1e5e3", "", True, QuotedNumber("1e5"), 10**19, "9" * 400, [1.0]):
        with pytest.raises(UserError, match="^x: "):
            number(bad, "x")


def test_probe_accepts_a_real_scheduler():
    """The handshake probe lets a Dask scheduler through (it greets first: distributed.comm.core.on_connection)."""
    import asyncio

    from distributed import Scheduler

    from pipeline.core.dask_client import probe

    async def run():
        async with Scheduler(host="127.0.0.1", port=0, dashboard_address=None) as s:
            await asyncio.get_running_loop().run_in_executor(None, probe, s.address)

    asyncio.run(run())


def test_a_sweep_whose_scheduler_fails_leaves_no_new_folder(tmp_path, ports):
    """Past the command's probe (here: called directly), a backend that fails before any chunk removes the --out
    folder this run created: no .sweep.lock, no metadata.json left behind."""
    from pipeline.core.errors import UserError
    from pipeline.datasets.dask_backend import DaskBackend
    from pipeline.datasets.runner import run_sweep
    from pipeline.datasets.spec import default_spec_dict, make_spec

    spec = make_spec({**default_spec_dict(), "n_points": 2})
    with pytest.raises(UserError, match="cannot reach"):
        run_sweep(spec, tmp_path / "new", backend=DaskBackend(f"tcp://127.0.0.1:{ports['closed']}"), progress=False)
    assert not (tmp_path / "new").exists()
