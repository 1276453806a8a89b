"""Errors that are the user's to fix: reported as one line by the CLI, never as a traceback."""
from sim.errors import ParameterError


class UserError(ValueError):
    """Bad input (file, column, option) — the message says what and where."""


USER_ERRORS = (UserError, ParameterError, FileNotFoundError, NotADirectoryError, IsADirectoryError, PermissionError)
