"""``vibro models``: list models, presets, parameters (name, default, unit) and effects."""
from __future__ import annotations


def add_parser(sub) -> None:
    p = sub.add_parser("models", help="list the models, their presets, parameters and effects",
                       description="List every model (or one) with its presets, parameters (name, default, unit, "
                                   "meaning) and the MODELS.md §6 effects it supports.")
    p.add_argument("model", nargs="?", help="show only this model")
    p.set_defaults(func=run)


def run(args) -> int:
    from sim import get_model, model_names

    names = [args.model] if args.model else list(model_names())
    for name in names:
        spec = get_model(name)
        print(f"{spec.name}: {spec.description}")
        if spec.presets:
            print(f"  presets: {', '.join(spec.presets)}")
        if spec.effects:
            print("  effects: " + "; ".join(f"{k} ({', '.join(v)})" for k, v in spec.effects.items()))
        for prm in spec.params:
            default = "derived" if prm.default is None else f"{prm.default:g}"
            print(f"    {prm.name:<16} {default:>10} {prm.unit:<8} {prm.description}")
        print()
    return 0
