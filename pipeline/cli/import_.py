"""``vibro import``: rig files (TDMS, HDF5, MATLAB .mat, CSV with units) -> a measured dataset (MODELS.md §7)."""
from __future__ import annotations

import argparse
import sys

from pipeline.cli import args as A
from pipeline.core.errors import UserError
from pipeline.core.units import G

EPILOG = """\
The mapping file (YAML) says which channel is which §7 signal, in which unit, and what the run table holds.
Paths are relative to the mapping file; a number is in the unit its column's name says (frequency_hz in Hz,
gap_m in m), a "VALUE UNIT" string is converted ("0.8 kN", "0.5 mm"), {property: NAME, unit: U} reads the value
from the file (TDMS property, HDF5 attribute, MATLAB scalar variable; the run's group first, then the file).

  file: rig-log.tdms              # every run's file unless a run names its own (format from the extension:
                                  # .tdms, .h5/.hdf5, .mat, .csv; or format: tdms | hdf5 | mat | csv)
  channels:                       # §7 signal: channel (inside the run's group)
    accel_m_s2: {channel: Accel, unit: g}
    force_n: {channel: "Load cell", unit: kN}
    disp_m: LVDT                  # unit from the file (TDMS unit_string, HDF5 attribute unit, CSV "disp [mm]")
  time: {channel: Time, unit: ms, start: first}   # or {rate_hz: 25600}; or leave out: TDMS wf_increment
  run_defaults: {system: drill, preset: lab, gap_m: 0}
  runs:
    - run_id: r01
      group: "Run 001"            # TDMS group, HDF5 group, MATLAB struct ('' = top level)
      frequency_hz: {property: "Forcing frequency"}
      amplitude_n: "0.8 kN"
      static_force_n: {property: "Static load", unit: kN}
      record_start_s: 0.6
      summary: {rop_m_s: "1.2 mm/s"}          # optional summary.csv row
    - {run_id: r02, group: "Run 002", channels: {}, duration_s: 2.0, summary: {rop_m_s: "1.5 mm/s"}}
                                              # channels: {} = no series, a summary.csv row only

""" + f"""\
units (pipeline/core/units.py): s ms us | Hz kHz | m/s2 mm/s2 g (g = {G:g} m/s2, the project's) | N kN mN lbf |
  m cm mm um in | m/s mm/s m/min m/h.  A unit the mapping gives must agree with the file's; a channel with no
  unit in either, an unknown unit or one of the wrong quantity is an error naming the file and the channel.
time: t_s starts at 0 at forcing phase 0 (MODELS.md §7): a time channel is shifted by start (a value in its
  unit, or first = its first sample; earlier samples are dropped).  duration_s defaults to samples x step.
output: DIR/runs.csv, DIR/series/<run_id>.csv, DIR/summary.csv (when runs give summary values), checked as
  vibro diagnose checks a dataset and written atomically (nothing is written when anything is wrong).
examples:
  vibro import rig-mapping.yaml --out measured/rig-2026-03
  vibro diagnose measured/rig-2026-03 --out results/diagnose-rig
worked example: docs/import.md"""


def add_parser(sub) -> None:
    p = sub.add_parser("import", help="turn rig files (TDMS, HDF5, .mat, CSV with units) into a measured dataset",
                       description="Read rig files in the formats data-acquisition systems write (NI TDMS, HDF5, "
                                   "MATLAB .mat, CSV with units in the header) through a mapping file, convert "
                                   "every channel to SI and write the measured-data directory of MODELS.md §7 "
                                   "that vibro diagnose reads.",
                       epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("mapping", metavar="MAPPING.yaml", help="the mapping file (see below)")
    p.add_argument("--out", required=True, metavar="DIR", help="dataset directory to write")
    A.add_quiet(p)
    A.add_overwrite(p, "imported dataset")
    p.set_defaults(func=run)


def run(args) -> int:
    from pathlib import Path

    from pipeline.core.bounded import load_yaml
    from pipeline.core.outdir import check_out, prepare_out
    from pipeline.datasets.fieldformats import FieldFormatError, import_runs, open_file, parse_mapping
    from pipeline.datasets.measured import load_dataset, write_dataset

    path = Path(args.mapping)
    if not path.is_file():
        raise UserError(f"mapping file {path} not found")
    doc = load_yaml(path, str(path), floats_12=True)
    try:
        mapping = parse_mapping(doc, str(path), path.parent)
        inputs = [path, *dict.fromkeys(r.file for r in mapping.runs if r.file is not None)]
        check_out(args.out, inputs=inputs, overwrite=args.overwrite, marker="import")
        result = import_runs(mapping, open_file)
    except FieldFormatError as e:
        raise UserError(str(e)) from None
    with prepare_out(args.out, inputs=inputs, overwrite=args.overwrite, marker="import") as tmp:
        write_dataset(result.dataset, tmp)
        try:
            load_dataset(tmp)
        except UserError as e:
            raise UserError(f"the imported data fail the MODELS.md §7 check: {e}") from None
    if not args.quiet:
        for r in result.runs:
            if not r.samples:
                print(f"  {r.run_id}: summary only", file=sys.stderr)
                continue
            conv = ", ".join(f"{c.signal} <- {c.channel} [{c.unit}] x {c.factor:g}" for c in r.conversions)
            print(f"  {r.run_id}: {r.samples} samples at {r.rate_hz:.6g} Hz (t_s from {r.time_from}); {conv}",
                  file=sys.stderr)
    print(f"wrote {len(result.runs)} runs to {args.out}")
    return 0
