"""Rig files: a rig (``sim.Rig``) as a small YAML document, read and written by the commands.

Format (README.md "Rig files")::

    model: drill                  # required: a model name (vibro models)
    preset: lab                   # optional: a preset of that model
    parameters: {K1: 5.2e8}       # optional: parameter -> value [SI], overriding the preset
    effects:                      # optional: MODELS.md §6 effect -> {parameter -> value}
      shaker_coil: {tau: 1.0e-4, beta: 3000.0}
    uncertainty: {K1: 2.0e7}      # optional: standard deviation of fitted values [same unit]
    model_error:                  # optional: what the fitted model still gets wrong about ROP (docs/optimise.md)
      rop_rel: 0.04               #   relative sd of its ROP [1]: the diagnosis's held-out rms ROP error
      noise_floor_rel: 0.01       #   optional: the same for pure measurement noise [1]
      basis: "held-out ROP of 3 runs"   # optional free text
    source: "vibro diagnose measured/drill-rig"   # optional free text
    exciter:                      # optional: the shaker's envelope, honoured by optimise (pipeline/optimise/envelope.py)
      max_force_n: {frequency_hz: [100, 450], amplitude_n: [2700, 2000]}
      max_stroke_m: 1.5e-3
      max_velocity_m_s: 0.4

Unknown keys, models, presets, parameters and effects are refused with one line naming them.
"""
from __future__ import annotations

import os
from pathlib import Path

from pipeline.core.errors import UserError
from vibrobase.files import atomic_write_text

HEADER = """\
# vibro rig file (README.md "Rig files"): the model, its preset, parameter values overriding the preset [SI],
# the MODELS.md §6 effects that are on with their parameters, standard deviations of fitted values, the model's
# remaining relative ROP error (model_error), an empirical ROP correction where no physics explained the data
# (empirical_correction: "physics unknown", applied by optimise --simulator and compare), and the source.
# Use it with --rig FILE in every command that simulates (simulate, sweep, map, optimise, verify, train --adaptive).
"""


def rig_name(path: str | os.PathLike | None) -> str | None:
    """A rig's name for people and MLflow: its file's stem (``my-rig.yaml`` -> ``my-rig``); a file the diagnosis
    wrote (``rig.yaml``, ``rig-metal.yaml``) takes its folder's name (``results/diagnose/drill-rig/rig.yaml`` ->
    ``drill-rig``).  None without a path."""
    if not path:
        return None
    p = Path(path)
    if p.stem == "rig" or p.stem.startswith("rig-"):
        return p.parent.resolve().name + p.stem[3:]
    return p.stem


def read_rig(path: str | os.PathLike):
    """The validated ``sim.Rig`` of a rig file (UserError naming the file and the culprit)."""
    from pipeline.core.bounded import load_yaml
    from sim import ParameterError, Rig

    p = Path(path)
    if not p.exists():
        raise UserError(f"rig file {p}: not found")
    data = load_yaml(p, f"rig file {p}", floats_12=True)
    if isinstance(data, dict):
        data = {k: v for k, v in data.items() if k != "exciter"}      # the command's (read_exciter), not the model's
    data = _numbers_checked(data, f"rig file {p}")
    if isinstance(data, dict) and isinstance(data.get("discrepancy"), dict):
        check_mode_complete(data["discrepancy"], f"rig file {p}: discrepancy")
    try:
        return Rig.from_mapping(data)
    except ParameterError as e:
        raise UserError(f"rig file {p}: {str(e).removeprefix('rig: ')}") from None


def read_exciter(path: str | os.PathLike) -> dict | None:
    """The ``exciter`` mapping of a rig file (the shaker's envelope), None when it declares none; the rig itself is
    checked by :func:`read_rig`, the mapping by ``pipeline.optimise.envelope.Envelope.from_mapping``."""
    from pipeline.core.bounded import load_yaml

    data = load_yaml(Path(path), f"rig file {path}", floats_12=True)
    return data.get("exciter") if isinstance(data, dict) else None


def check_mode_complete(values: dict, label: str) -> None:
    """UserError when the hidden load-path mode's frequency or damping is given without its mass ratio: with
    the ratio 0 (its default) the mode is off, and the other two would be silently ignored."""
    from sim.models.discrepancy import MODE_PARAMS

    ratio, *rest = MODE_PARAMS
    given = [n for n in rest if values.get(n)]
    if given and not values.get(ratio):
        raise UserError(f"{label} {given[0]} without {ratio}: the mode is off while {ratio} is 0; "
                        f"give {ratio} > 0 or leave the mode out")


def _numbers_checked(data, label: str):
    """``data`` with every value of parameters, effects, discrepancy, uncertainty and the model error's numbers through
    the one number parser (quoted text, booleans and out-of-range integers refused naming the value); other shapes
    unchanged, for ``Rig.from_mapping`` to name."""
    from collections.abc import Mapping

    from pipeline.core.numbers import number

    if not isinstance(data, Mapping):
        return data
    out = dict(data)
    for key, what in (("parameters", "parameter"), ("discrepancy", "discrepancy term"),
                      ("uncertainty", "uncertainty of")):
        if isinstance(out.get(key), Mapping):
            out[key] = {n: number(v, f"{label}: {what} '{n}'") for n, v in out[key].items()}
    if isinstance(out.get("model_error"), Mapping):
        out["model_error"] = {n: (number(v, f"{label}: model_error {n}") if n in ("rop_rel", "noise_floor_rel")
                                  and v is not None else v) for n, v in out["model_error"].items()}
    if isinstance(out.get("effects"), Mapping):
        out["effects"] = {e: ({n: number(v, f"{label}: effect '{e}' parameter '{n}'") for n, v in vals.items()}
                              if isinstance(vals, Mapping) else vals) for e, vals in out["effects"].items()}
    return out


def write_rig(path: str | os.PathLike, rig, comment: str = "") -> Path:
    """Write ``rig`` (a ``sim.Rig``) atomically as a rig file, with the format header and an optional comment."""
    import yaml

    extra = "".join(f"# {line}\n" for line in comment.splitlines())
    body = yaml.safe_dump(rig.to_mapping(), sort_keys=False, default_flow_style=False)
    return atomic_write_text(path, HEADER + extra + body)
