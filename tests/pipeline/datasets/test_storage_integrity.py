"""Reliability of the sweep's storage: the exclusive lock under concurrency, per-chunk checksums,
and --overwrite that never deletes files the sweep did not write."""
from __future__ import annotations

import multiprocessing as mp
import os
import time
from pathlib import Path

import pandas as pd
import pytest

from pipeline.core.errors import UserError
from pipeline.core.integrity import (DirLock, LockBusy, checksum_path, sha256_file, verify_checksum,
                                write_with_checksum)
from pipeline.datasets.runner import run_sweep
from pipeline.datasets.spec import make_spec
from pipeline.datasets.store import LOCK_NAME, load_dataset

from tests.pipeline.datasets.test_sweep import raw_spec


# ------------------------------------------------------------------------------------- lock
def _contender(lock_path: str, barrier, hold_s: float, results) -> None:
    barrier.wait()
    try:
        lk = DirLock(lock_path).acquire()
    except LockBusy:
        results.put(0)
        return
    time.sleep(hold_s)          # hold it long enough that the other contender surely tries meanwhile
    lk.release()
    results.put(1)


def _race(lock_path: Path, rounds: int, n_procs: int = 2, stale: bool = False) -> list[int]:
    """Winners per round of ``n_procs`` processes released at once by a barrier."""
    ctx = mp.get_context("fork")
    winners = []
    for _ in range(rounds):
        if stale:   # a lock file left by a killed process (dead pid); flock makes its content irrelevant
            lock_path.write_text(f"{os.uname().nodename} 999999999\n")
        barrier, results = ctx.Barrier(n_procs), ctx.Queue()
        procs = [ctx.Process(target=_contender, args=(str(lock_path), barrier, 0.05, results)) for _ in range(n_procs)]
        for p in procs:
            p.start()
        for p in procs:
            p.join(30)
        winners.append(sum(results.get(timeout=5) for _ in procs))
    return winners


@pytest.mark.parametrize("stale", [False, True], ids=["no-stale-lock", "stale-lock"])
def test_concurrent_lockers_exactly_one_wins(tmp_path, stale):
    """The old O_EXCL+unlink lock let two processes both win 21/300 times with a stale lock present."""
    winners = _race(tmp_path / LOCK_NAME, rounds=25, n_procs=3, stale=stale)
    assert winners == [1] * 25


@pytest.mark.slow
@pytest.mark.parametrize("stale", [False, True], ids=["no-stale-lock", "stale-lock"])
def test_concurrent_lockers_300_rounds(tmp_path, stale):
    winners = _race(tmp_path / LOCK_NAME, rounds=300, n_procs=2, stale=stale)
    assert winners == [1] * 300


def test_lock_is_exclusive_within_a_process_and_reusable(tmp_path):
    lk = DirLock(tmp_path / "x.lock", what="sweep").acquire()
    with pytest.raises(LockBusy, match=rf"another sweep \(host/pid \S+ {os.getpid()}\)"):
        DirLock(tmp_path / "x.lock", what="sweep").acquire()
    lk.release()
    assert (tmp_path / "x.lock").exists()            # never deleted: no inode race
    with DirLock(tmp_path / "x.lock") as again:
        assert again.held
    assert not again.held


def test_lock_of_a_killed_process_does_not_block(tmp_path):
    """kill -9 of the holder: the kernel drops the flock; the file stays and is taken at once."""
    ctx = mp.get_context("fork")
    ready = ctx.Event()

    def hold():
        DirLock(tmp_path / LOCK_NAME).acquire()
        ready.set()
        time.sleep(60)

    p = ctx.Process(target=hold)
    p.start()
    assert ready.wait(30)
    with pytest.raises(LockBusy):
        DirLock(tmp_path / LOCK_NAME).acquire()
    p.kill()
    p.join(10)
    with DirLock(tmp_path / LOCK_NAME):
        pass


def test_running_sweep_refuses_a_second_writer(tmp_path):
    out = tmp_path / "ds"
    out.mkdir()
    with DirLock(out / LOCK_NAME, what="sweep"):
        with pytest.raises(UserError, match="another sweep"):
            run_sweep(make_spec(raw_spec(n_points=2, chunk_size=2)), out, progress=False)


# -------------------------------------------------------------------------------- checksums
def test_checksum_sidecar_roundtrip_and_detection(tmp_path):
    final = tmp_path / "f.bin"
    digest = write_with_checksum(final, lambda tmp: Path(tmp).write_bytes(b"abc" * 1000))
    assert final.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["f.bin", "f.bin.sha256"]  # no temporaries
    # sha256sum format: "<hex>  <name>"
    assert checksum_path(final).read_text() == f"{digest}  f.bin\n"
    assert digest == sha256_file(final)
    assert verify_checksum(final) is None
    data = bytearray(final.read_bytes())
    data[1500] ^= 0x01
    final.write_bytes(bytes(data))
    assert "differs from the recorded" in verify_checksum(final)
    checksum_path(final).unlink()
    assert "no checksum file" in verify_checksum(final)


def _flip_two_bytes_in_data_pages(p: Path) -> None:
    """Flip two bytes of a column's data page, leaving the Parquet footer (and so its metadata) intact."""
    import pyarrow.parquet as pq

    md = pq.read_metadata(p)
    col = md.row_group(0).column(md.num_columns - 1)      # last column's data page: far from the footer
    off = (col.dictionary_page_offset or col.data_page_offset) + col.total_compressed_size // 2
    data = bytearray(p.read_bytes())
    data[off] ^= 0xFF
    data[off + 1] ^= 0xFF
    p.write_bytes(bytes(data))
    pq.read_metadata(p)             # the footer still reads: only a checksum can notice


def test_corrupt_chunk_is_recomputed_and_said_so(tmp_path, capfd):
    """Issue 15: two flipped bytes inside a chunk with an intact footer were reused on resume."""
    out = tmp_path / "ds"
    spec = make_spec(raw_spec(n_points=4, chunk_size=2))
    run_sweep(spec, out, progress=False)
    clean = load_dataset(out)
    part = out / "part-00001.parquet"
    assert checksum_path(part).exists()
    _flip_two_bytes_in_data_pages(part)
    capfd.readouterr()
    s = run_sweep(spec, out, progress=False)
    err = capfd.readouterr().err
    assert "part-00001.parquet" in err and "recomputed" in err and "differs from the recorded" in err
    assert s.computed == 2 and s.reused == 2
    pd.testing.assert_frame_equal(load_dataset(out), clean, check_exact=True)
    assert verify_checksum(part) is None


def test_chunk_without_checksum_is_recomputed(tmp_path, capfd):
    out = tmp_path / "ds"
    spec = make_spec(raw_spec(n_points=4, chunk_size=2))
    run_sweep(spec, out, progress=False)
    checksum_path(out / "part-00000.parquet").unlink()
    s = run_sweep(spec, out, progress=False)
    assert "no checksum file" in capfd.readouterr().err
    assert s.computed == 2 and s.reused == 2


# ------------------------------------------------------------------------------- overwrite
def test_overwrite_refuses_files_the_sweep_did_not_write(tmp_path):
    """Issue 15: `sweep --overwrite` deleted any part-*.parquet in the folder, also ones it did not write."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    out = tmp_path / "ds"
    spec = make_spec(raw_spec(n_points=2, chunk_size=2))
    run_sweep(spec, out, progress=False)
    user_part = out / "part-00007.parquet"
    pq.write_table(pa.table({"x": [1.0]}), user_part)      # a user's file that happens to match the glob
    notes = out / "notes.txt"
    notes.write_text("mine")
    with pytest.raises(UserError, match=r"did not write.*notes.txt|did not write.*part-00007"):
        run_sweep(spec, out, progress=False, overwrite=True)
    assert user_part.exists() and notes.read_text() == "mine"
    notes.unlink()
    with pytest.raises(UserError, match="part-00007.parquet"):
        run_sweep(spec, out, progress=False, overwrite=True)
    user_part.unlink()
    s = run_sweep(spec, out, progress=False, overwrite=True)      # only its own files: replaced
    assert s.computed == 2


# ------------------------------------------------------------------------------------- foreign files
def test_single_parquet_without_point_id_loads_in_file_order(tmp_path):
    # e.g. a simulate_batch table saved by hand (README: `vibro train` takes "one .parquet file"); this
    # used to end in "internal error: KeyError: 'point_id'"
    df = pd.DataFrame({"frequency_hz": [300.0, 100.0, 200.0], "rop_m_s": [1e-3, 2e-3, 3e-3]})
    f = tmp_path / "batch.parquet"
    df.to_parquet(f)
    got = load_dataset(f)
    assert got["frequency_hz"].tolist() == [300.0, 100.0, 200.0]


def test_dataset_part_without_point_id_is_a_user_error(tmp_path):
    pd.DataFrame({"frequency_hz": [100.0]}).to_parquet(tmp_path / "part-00000.parquet")
    with pytest.raises(UserError, match=r"part-00000.parquet: no 'point_id' column"):
        load_dataset(tmp_path, allow_partial=True)
