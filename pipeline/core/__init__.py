"""The foundation every other package may import: errors, atomic files, params.yaml sections, shared names.

errors.py    UserError and the tuple of errors the CLI reports as one line
files.py     the atomic-write helpers (text, bytes, JSON, Parquet, whole directories), from ``vibrobase.files``
params.py    the one params.yaml section reader
numbers.py   the one number parser (flags, YAML, CSV cells): finite, integers as integers, no text coercion
bounded.py   size-capped reads and the YAML loader (no aliases, duplicate keys, deep nesting or huge integers)
rigfile.py   rig files read (every value through numbers.py) and written
names.py     sweep statuses (from ``vibrobase.statuses``), the objective's sense and display units
jsonable.py  JSON-safe conversion and the nested-dict flattener, from ``vibrobase.jsonable``
dask_client.py  a Dask scheduler address (tcp://host:port or local:N) checked and connected
executors.py    batches of independent tasks run in this process or on a Dask cluster, results in order
units.py        engineering units for people; a lab's units to SI (``SI_UNITS``, ``column_factor``)
optional.py     ``try_import``: an optional third-party package guarded once

The range <-> unit-interval mapping is ``vibrobase.unitcube``; the surrogate's regimes and targets are
``surrogate.names``.  It imports nothing of the project but ``sim`` (for ParameterError and LABELS).
"""
