"""``vibro models [MODEL]``: the models; for one model every parameter with its default and every preset's values."""
from __future__ import annotations

import argparse


def add_parser(sub) -> None:
    p = sub.add_parser(
        "models", help="list the models; 'vibro models MODEL' shows parameters, presets, effects, fit bounds",
        description="Without MODEL: every model with its presets, effects and parameters (name, default, unit, "
                    "meaning).  With MODEL: also the value of every parameter in every preset (a blank cell = the "
                    "default), the MODELS.md §6 effects with their parameters and fit bounds, the calibratable "
                    "parameters (what 'vibro diagnose' fits) and the search spaces (the default sweep and "
                    "optimisation ranges).",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n  vibro models\n  vibro models drill\n  vibro models indenter-metal")
    p.add_argument("model", nargs="?", help="show this model in full")
    p.set_defaults(func=run)


def _g(v) -> str:
    return "derived" if v is None else f"{v:g}"


def describe(name: str, full: bool) -> list[str]:
    """Lines describing model ``name`` (``full``: presets' values, effects' bounds, calibratable, search spaces)."""
    from sim import get_model
    from sim.models.discrepancy import COMPANION, PARAM_OF as DISCREPANCY_PARAMS

    spec = get_model(name)
    lines = [f"{spec.name}: {spec.description}"]
    if spec.presets:
        lines.append(f"  presets: {', '.join(spec.presets)}")
    if spec.effects:
        lines.append("  effects: " + "; ".join(f"{k} ({', '.join(v)})" for k, v in spec.effects.items()))
    presets = list(spec.presets) if full else []
    # a term this model does not offer: its parameter must stay 0, so it is not listed
    shown = [prm for prm in spec.params if not ((prm.name in DISCREPANCY_PARAMS or prm.name in COMPANION)
                                                and COMPANION.get(prm.name, prm.name) not in spec.discrepancy)]
    w = max(16, *(len(prm.name) for prm in shown))
    head = f"    {'parameter':<{w}} {'default':>10} " + "".join(f"{p:>14} " for p in presets) + f"{'unit':<8} meaning"
    lines.append(head)
    for prm in shown:
        cells = "".join(f"{_g(spec.presets[p][prm.name]) if prm.name in spec.presets[p] else '':>14} "
                        for p in presets)
        lines.append(f"    {prm.name:<{w}} {_g(prm.default):>10} {cells}{prm.unit:<8} {prm.description}")
    if not full:
        return lines
    units = {p.name: p.unit for p in spec.params}
    if spec.effects:
        lines.append("  effects (MODELS.md §6; all off at 0) with fit bounds:")
        for eff, names in spec.effects.items():
            parts = []
            for n in names:
                b = spec.effect_bounds.get(n)
                parts.append(f"{n} [{b.lo:g} .. {b.hi:g}] {units.get(n, b.unit)}" if b else n)
            lines.append(f"    {eff:<22} " + "; ".join(parts))
    if spec.calibratable:
        lines.append("  calibratable (fitted by 'vibro diagnose', perturbed by 'vibro synth'):")
        for b in spec.calibratable:
            lines.append(f"    {b.name:<16} [{b.lo:g} .. {b.hi:g}] {b.unit}{' (log)' if b.log else ''}")
    if spec.search_spaces:
        lines.append("  search spaces (default sweep 'vary' and optimisation space):")
        for preset, space in spec.search_spaces.items():
            rng = ", ".join(f"{k} {lo:g}..{hi:g} {units.get(k, '')}".rstrip() for k, (lo, hi) in space.items())
            lines.append(f"    {preset or '(defaults)':<16} {rng}")
    if spec.validated:
        lines.append("  validated on (a value outside draws a warning; with the calibratable bounds above):")
        for preset, space in spec.validated.items():
            rng = ", ".join(f"{k} {lo:g}..{hi:g} {units.get(k, '')}".rstrip() for k, (lo, hi) in space.items())
            lines.append(f"    {preset or '(defaults)':<16} {rng or 'its own values only'}")
    return lines


def run(args) -> int:
    from sim import model_names

    from pipeline.core.errors import UserError
    from vibrobase.errors import did_you_mean

    if args.model and args.model not in model_names():
        raise UserError(f"unknown model '{args.model}'{did_you_mean(args.model, model_names())}; "
                        f"known models: {', '.join(model_names())}")
    names = [args.model] if args.model else list(model_names())
    for name in names:
        print("\n".join(describe(name, full=bool(args.model))))
        print()
    return 0
