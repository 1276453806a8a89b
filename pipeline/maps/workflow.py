"""``run_map``: compute one response map or bifurcation diagram and write its PNG and Parquet files.

The ``vibro map`` command parses and validates the flags into a :class:`MapConfig`, calls :func:`run_map`
inside its MLflow run, logs and prints the :class:`MapResult`.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from vibrobase.statuses import BOUNDED_STATUSES
from pipeline.maps import compute as M
from pipeline.maps import plot as P


@dataclass(frozen=True)
class MapConfig:
    """One map: model, kind (peterka, rop, label or bifurcation), axis values and where the files go."""
    model: str
    kind: str
    x: str
    xs: np.ndarray                   # --x values [parameter units]
    out: Path                        # output prefix: writes <out>.png and <out>.parquet (+ .strobe.parquet)
    y: str | None = None
    ys: np.ndarray | None = None     # --y values (2-D maps only)
    color: str = "peak_force_n"      # label colouring the map
    direction: str = "both"          # bifurcation sweep direction: up, down or both
    preset: str | None = None
    fixed: dict = field(default_factory=dict)
    settings: dict | None = None
    threads: int | None = None

    @property
    def png(self) -> Path:
        return self.out.with_name(self.out.name + ".png")

    @property
    def parquet(self) -> Path:
        return self.out.with_name(self.out.name + ".parquet")


@dataclass(frozen=True)
class MapResult:
    """The labelled points, the files written, the impact-pattern counts and the wall time [s]."""
    table: pd.DataFrame
    files: list[Path]
    counts: dict[str, int]
    wall_s: float


def run_map(cfg: MapConfig, progress: bool = True) -> MapResult:
    """Compute the map of ``cfg`` (progress bar on stderr when ``progress``) and write its files."""
    from tqdm import tqdm

    t0 = time.perf_counter()
    png, pq = cfg.png, cfg.parquet
    title_fixed = ", ".join(f"{k}={v:g}" for k, v in cfg.fixed.items())
    if cfg.kind == "bifurcation":
        n = cfg.xs.size * (2 if cfg.direction == "both" else 1)
        with tqdm(total=n, desc=f"{cfg.model} {cfg.x} sweep", unit="pt", disable=not progress) as bar:
            pts, strobe = M.bifurcation(cfg.model, cfg.x, cfg.xs, cfg.direction, cfg.preset, cfg.fixed, cfg.settings,
                                        progress=bar.update)
        strobe_pq = cfg.out.with_name(cfg.out.name + ".strobe.parquet")
        M.write_parquet(pts, pq)
        M.write_parquet(strobe, strobe_pq)
        P.plot_bifurcation(pts, strobe, cfg.x, png,
                           title=f"{cfg.model} bifurcation diagram ({cfg.direction}) {title_fixed}")
        table, files = pts, [png, pq, strobe_pq]
    else:
        with tqdm(total=cfg.xs.size * cfg.ys.size, desc=f"{cfg.model} {cfg.kind} map", unit="cell",
                  disable=not progress) as bar:
            table = M.grid_map(cfg.model, cfg.x, cfg.xs, cfg.y, cfg.ys, cfg.preset, cfg.fixed, cfg.settings,
                               n_threads=cfg.threads, progress=bar.update)
        M.write_parquet(table, pq)
        title = f"{cfg.model} {cfg.kind} map {title_fixed}"
        if cfg.kind == "peterka":
            P.plot_peterka(table, cfg.x, cfg.y, png, color=cfg.color, title=title)
        else:
            if cfg.kind == "label" or "rop_region" not in table:
                table = table.assign(rop_region=[M.ROP_OK if s in BOUNDED_STATUSES else
                                                 (M.ROP_RUNAWAY if s == "runaway" else M.ROP_FAILED)
                                                 for s in table["status"]])
            P.plot_rop(table, cfg.x, cfg.y, png, color=cfg.color, title=title)
        files = [png, pq]
    counts = {str(k): int(v) for k, v in table["pattern_name"].value_counts().to_dict().items()}
    return MapResult(table, files, counts, time.perf_counter() - t0)
