"""Labelled datasets: sweeps of the simulator and measured rig data.

spec.py          sweep specification (model, preset, fixed, varied ranges, design, settings) and design points
designs.py       designs in the unit cube: scrambled Sobol', Latin hypercube, Sobol' with points on the boundary
store.py         the on-disk sweep dataset: schema, chunk files, metadata, lock, provenance, ``load_dataset``
compute.py       one chunk simulated (what a backend runs)
runner.py        ``run_sweep`` on a backend (``LocalBackend``; any object with ``run(spec, chunks, write)``)
dask_backend.py  ``DaskBackend``: chunks as tasks on a Dask cluster
measured.py      measured rig data (MODELS.md §7): reader and writer
fieldformats/    rig files (TDMS, HDF5, MATLAB .mat, CSV with units) -> §7 through a mapping (vibro import)
plot.py          the sweep's overview figure
"""
