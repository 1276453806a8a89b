"""The atomic-write helpers, for the pipeline: they live in ``sim.files`` (a lower layer), so the surrogate
library writes its bundles and figures the same way without importing the application."""
from sim.files import (atomic_directory, atomic_write_bytes, atomic_write_figure, atomic_write_json,
                       atomic_write_parquet, atomic_write_text, atomic_write_with, clean_stale_temps,
                       duplicate_csv_column)

__all__ = ["atomic_directory", "atomic_write_bytes", "atomic_write_figure", "atomic_write_json",
           "atomic_write_parquet", "atomic_write_text", "atomic_write_with", "clean_stale_temps",
           "duplicate_csv_column"]
