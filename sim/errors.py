"""The simulator's exception, in a module without numpy: ``pipeline.core.errors`` (hence every ``vibro --help``)
imports it, and it must not pay for numpy or numba."""


class ParameterError(ValueError):
    """Bad parameter name or value (message names the parameter)."""
