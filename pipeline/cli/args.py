"""``--set name=value`` parsing shared by the subcommands."""
from __future__ import annotations

from pipeline.core.errors import UserError


def parse_assignments(items: list[str] | None, what: str = "--set") -> dict[str, float]:
    """Parse ``["k1=1e7", "gap_m=0.001"]`` into floats; a clear error names the bad item."""
    out: dict[str, float] = {}
    for item in items or []:
        if "=" not in item:
            raise UserError(f"{what} expects name=value, got '{item}'")
        name, _, raw = item.partition("=")
        name = name.strip()
        if not name:
            raise UserError(f"{what} '{item}' has no parameter name")
        try:
            value = float(raw)
        except ValueError:
            raise UserError(f"{what} {name}: '{raw}' is not a number") from None
        out[name] = value
    return out
