"""The foundation every other package may import: errors, atomic files, params.yaml sections, shared names.

errors.py    UserError and the tuple of errors the CLI reports as one line
files.py     the one atomic-write module (text, bytes, JSON, Parquet, whole directories; fsync + os.replace)
params.py    the one params.yaml section reader
names.py     label names, surrogate targets, regimes and the regime <-> sweep-status map
jsonable.py  JSON-safe conversion and the one nested-dict flattener
unitcube.py  the one range <-> unit-interval mapping (linear or log)

It imports nothing of the project but ``sim`` (for ParameterError and LABELS).
"""
