"""Optional third-party packages, guarded once: ``try_import`` defers a missing package to the moment the
feature that needs it is used, and says what to install."""
from __future__ import annotations

import importlib
from types import ModuleType


class MissingPackage(ImportError):
    """An optional package a feature needs is not installed (the message says which and how to install it)."""


def try_import(module: str, *, package: str, feature: str) -> ModuleType:
    """Module ``module``, or MissingPackage naming ``package`` (the pip name) and ``feature`` (what needs it)."""
    try:
        return importlib.import_module(module)
    except ImportError as e:
        if e.name is not None and e.name.split(".")[0] != module.split(".")[0]:
            raise                      # the package is there but broken inside: not a missing package
        raise MissingPackage(f"{feature} needs the Python package {package} (pip install {package})") from None
