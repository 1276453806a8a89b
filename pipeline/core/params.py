"""The one params.yaml section reader."""
from __future__ import annotations

import os
from pathlib import Path
from typing import Iterable

from pipeline.core.errors import UserError
from vibrobase.errors import did_you_mean


def read_params(path: str | os.PathLike, missing_ok: bool = False) -> dict:
    """The whole params file as a dict; ``{}`` when ``missing_ok`` and it does not exist (UserError on bad YAML)."""
    from pipeline.core.bounded import load_yaml

    p = Path(path)
    if missing_ok and not p.exists():
        return {}
    data = load_yaml(p, str(p)) or {}
    if not isinstance(data, dict):
        raise UserError(f"{p}: must be a mapping of sections")
    return data


def read_section(path: str | os.PathLike | None, section: str, *, section_required: bool = False,
                 missing_file_ok: bool = False, known: Iterable[str] | None = None) -> dict:
    """The ``section`` mapping of a params.yaml.

    ``path`` None gives ``{}``; a missing file is FileNotFoundError unless ``missing_file_ok``; a missing section
    is ``{}`` unless ``section_required`` (then a UserError naming the file); ``known`` lists the allowed keys (an
    unknown key is a UserError naming it as ``section.key``)."""
    if path is None:
        return {}
    p = Path(path)
    if not p.exists():
        if missing_file_ok:
            return {}
        raise FileNotFoundError(2, "No such file or directory", str(p))
    data = read_params(p)
    if data.get(section) is None:
        if section_required:
            raise UserError(f"{p}: no '{section}' section")
        return {}
    sec = data[section]
    if not isinstance(sec, dict):
        raise UserError(f"{p}: section '{section}' must be a mapping")
    if known is not None:
        unknown = sorted(set(sec) - set(known))
        if unknown:
            raise UserError(f"{p}: {section}.{unknown[0]} is not a known key{did_you_mean(unknown[0], known)} "
                            f"(known: {', '.join(sorted(known))})")
    return dict(sec)
