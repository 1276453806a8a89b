"""The base of the project's bad-input errors and the one spelling-suggestion helper, in a module without numpy:
``pipeline.core.errors`` (hence every ``vibro --help``) imports it, and it must not pay for numpy or numba."""
from __future__ import annotations

import difflib
from typing import Iterable


class InputError(ValueError):
    """Bad input the caller can fix (a name, a value, a file), the message saying what and where: the base of
    ``sim.ParameterError``, ``surrogate.SurrogateError`` and ``pipeline.core.errors.UserError``.  A ValueError,
    as each of them was before it had this base."""


def did_you_mean(word: str, choices: Iterable[str]) -> str:
    """`` (did you mean NAME?)`` naming the choice closest to a mistyped ``word`` (difflib, case folded: ``k1``
    finds ``K1``, ``frequency`` finds ``frequency_hz``, ``--npoints`` finds ``--n-points``), or ``""`` when none
    is close.  Every "unknown name" message of the project appends it: flags, subcommands, models, presets,
    parameters, settings, rig-file and params-file keys."""
    by_fold: dict[str, str] = {}
    for c in choices:
        by_fold.setdefault(str(c).casefold(), str(c))
    w = str(word).casefold()
    if w in by_fold:                         # differs only in case
        return f" (did you mean {by_fold[w]}?)"
    close = difflib.get_close_matches(w, list(by_fold), n=1, cutoff=0.6)
    if not close:                            # a known name that starts or ends the typed one (frequency -> frequency_hz)
        close = [c for c in by_fold if len(w) >= 3 and (c.startswith(w) or w.startswith(c))][:1]
    return f" (did you mean {by_fold[close[0]]}?)" if close else ""
