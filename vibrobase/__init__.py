"""The bottom floor: infrastructure the simulator, the surrogate library and the application share.

It imports nothing of the project, and every other package may import it (tests/test_architecture.py).
Importing the package or errors.py, statuses.py, files.py or jsonable.py loads no numpy (every ``vibro --help``
imports errors.py); unitcube.py is numpy's.

errors.py    ``InputError`` (the base of the project's bad-input errors) and the one ``did_you_mean``
files.py     the one atomic-write module (text, bytes, JSON, Parquet, figures, whole directories; fsync + os.replace)
jsonable.py  JSON-safe conversion (numpy scalars, inf) and the one nested-dict flattener
statuses.py  the names of the simulator's per-point status and its groups (settled, bounded, impacting)
unitcube.py  the one mapping between a parameter range and the unit interval (linear or logarithmic)
"""
