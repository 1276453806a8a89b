"""The surrogate library's exceptions: bad input the caller can fix, each message saying what and where.

A command reports any :class:`SurrogateError` as one line; the subclasses let a caller tell what was wrong."""
from vibrobase.errors import InputError


class SurrogateError(InputError):
    """Base of every error the surrogate raises for bad input (configuration, data or bundle)."""


class ConfigError(SurrogateError):
    """A training configuration key, value or candidate name is not valid."""


class DataError(SurrogateError):
    """A dataset or a prediction input lacks a column, holds a bad value or lies outside the trained ranges."""


class BundleError(SurrogateError):
    """A bundle directory is missing, damaged, foreign, untrusted or trained on another model's data."""
