"""JSON-safe conversion and the nested-dict flattener, for the pipeline (they live in ``sim.jsonable``, a lower
layer, so the surrogate library shares them without importing the application)."""
from sim.jsonable import dump_json, flatten, to_jsonable

__all__ = ["to_jsonable", "dump_json", "flatten"]
