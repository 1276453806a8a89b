"""The application's foundation every workflow may import: errors, params.yaml sections, numbers, shared names.

errors.py    UserError and the tuple of errors the CLI reports as one line
params.py    the one params.yaml section reader
numbers.py   the one number parser (flags, YAML, CSV cells): finite, integers as integers, no text coercion
bounded.py   size-capped reads and the YAML loader (no aliases, duplicate keys, deep nesting or huge integers)
rigfile.py   rig files read (every value through numbers.py) and written
names.py     the objective's sense and display units
integrity.py checksummed files and the directory lock
outdir.py    output folders and files written whole or not at all
dask_client.py  a Dask scheduler address (tcp://host:port or local:N) checked and connected
executors.py    batches of independent tasks run in this process or on a Dask cluster, results in order
units.py        engineering units for people; a lab's units to SI (``SI_UNITS``, ``column_factor``)
optional.py     ``try_import``: an optional third-party package guarded once

Atomic files, JSON conversion, statuses and the range <-> unit-interval mapping are the bottom package's
(``vibrobase.files``, ``.jsonable``, ``.statuses``, ``.unitcube``); the surrogate's regimes and targets are
``surrogate.names``.  It imports nothing of the project but ``vibrobase`` and ``sim`` (for ParameterError and LABELS).
"""
