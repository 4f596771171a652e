"""Argument helpers shared by the commands (no heavy imports here)."""

from __future__ import annotations

import argparse


def assignments(items, what: str = "NAME=VALUE") -> dict[str, float]:
    """Parse ``["Cm_de=-1.4", ...]`` into ``{"Cm_de": -1.4}``."""
    from ..errors import ParameterError

    out = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise ParameterError(f"expected {what}, got {item!r}")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            raise ParameterError(f"{item!r}: {value!r} is not a number") from None
    return out


def add_model_arguments(p: argparse.ArgumentParser, *, default_model: str = "unsteady",
                        gust_flag: bool = True) -> None:
    """--aircraft, --model, --gust, --airspeed options shared by commands."""
    p.add_argument("--aircraft", metavar="NAME|FILE.json",
                   help="preset (navion, sundowner, do128) or an aircraft JSON file")
    p.add_argument("--model", default=default_model,
                   choices=("unsteady", "steady", "derivatives", "dimensional"),
                   help=f"model (default {default_model})")
    if gust_flag:
        p.add_argument("--gust", action="store_true", help="add the vertical gust input alpha_w")
    p.add_argument("--airspeed", type=float, metavar="U",
                   help="airspeed in m/s for the dimensional model without --aircraft")


def make_model_from_args(args, values: dict | None = None):
    """Build the model named by the arguments, with ``values`` set."""
    from ..errors import ParameterError
    from ..models import make_model

    if args.model == "dimensional":
        if args.aircraft is None and args.airspeed is None:
            raise ParameterError("the dimensional model needs --airspeed U (m/s) or --aircraft")
        opts = {"airspeed": args.airspeed} if args.airspeed is not None else {}
        model = make_model("dimensional", args.aircraft, gust=bool(args.gust), **opts)
    else:
        if args.aircraft is None:
            raise ParameterError(f"the {args.model} model needs --aircraft NAME or FILE.json")
        model = make_model(args.model, args.aircraft, gust=bool(args.gust))
    if values:
        model.parameters.check_names(values)
        model = model.with_values(values)
    return model
