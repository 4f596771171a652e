"""``fdml effects``: the library of effects a model can be given (``--effect NAME[:CHANNEL]``)."""

from __future__ import annotations


def register(sub) -> None:
    p = sub.add_parser(
        "effects",
        help="list the effects a model can include: channels, parameters, units, null values and plausible ranges",
    )
    from . import _options as O

    O.add_json_option(p)


def text(cat: list[dict]) -> str:
    """The catalogue as a text table: one block per effect, one line per parameter and base model."""
    lines = [
        "effects (use --effect NAME:CHANNEL); per base model:",
        f"    {'base models':40s} {'parameter':10s} {'unit':14s} {'null':10s} plausible range",
    ]
    for e in cat:
        lines.append("")
        kind = "" if e["kind"] == "deterministic" else f"  [{e['kind']}: tested by fdml diagnose only]"
        lines.append(f"{e['name']}:{e['channel']}{kind}  -  {e['signature']}")
        seen: dict = {}
        for model, pars in e["parameters"].items():  # models sharing one parameter list on one line
            key = tuple(p["name"] for p in pars)
            seen.setdefault(key, ([], pars))[0].append(model)
        for models, pars in seen.values():
            for p in pars:
                lo, hi = p["plausible"] or (None, None)
                span = "-" if lo is None else f"{lo:g} .. {hi:g}"
                null = "base value" if p["null"] is None else f"{p['null']:g}"
                lines.append(f"    {','.join(models):40s} {p['name']:10s} {p['unit'] or '-':14s} {null:10s} {span}")
    return "\n".join(lines)


def run(args) -> int:
    from ..cli import show
    from ..models.effects import catalogue

    cat = catalogue()
    show(args, {"effects": cat}, text(cat))
    return 0
