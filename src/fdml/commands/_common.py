"""Argument helpers shared by the commands (no heavy imports here)."""

from __future__ import annotations

import argparse
import math


def default_model(args) -> str:
    """The model kind by the one rule: --model, else unsteady with --aircraft, else dimensional."""
    if getattr(args, "model", None):
        return args.model
    return "unsteady" if getattr(args, "aircraft", None) is not None else "dimensional"


def assignments(items, what: str = "NAME=VALUE") -> dict[str, float]:
    """Parse ``["Cm_de=-1.4", ...]`` into ``{"Cm_de": -1.4}``."""
    from ..errors import ParameterError

    out: dict[str, float] = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise ParameterError(f"expected {what}, got {item!r}")
        try:
            number = float(value)
        except ValueError:
            raise ParameterError(f"{item!r}: {value!r} is not a number") from None
        if not math.isfinite(number):  # float() reads nan and inf: no parameter value is either
            raise ParameterError(f"{item!r}: {value.strip()!r} is not a finite number")
        if name.strip() in out and out[name.strip()] != number:
            raise ParameterError(f"{item!r}: {name.strip()} is already given as {out[name.strip()]:g}")
        out[name.strip()] = number
    return out


def noise_option(text: str | None):
    """``--noise``: ``0.02`` (a fraction of each output's RMS) or ``alpha=1e-3,q=2e-3,az=0.01`` (stds); None: not given.

    The level is checked by :func:`fdml.record.check_noise`, the library's one check.
    """
    if text is None:
        return None
    from ..errors import RecordError
    from ..record import check_noise

    if "=" in text:
        return check_noise(assignments(text.split(","), "alpha=STD,q=STD,az=STD"))
    try:
        return check_noise(float(text))
    except ValueError:
        raise RecordError(f"--noise {text!r}: give a fraction of RMS (0.02) or alpha=..,q=..,az=..") from None


def add_effect_argument(p: argparse.ArgumentParser) -> None:
    """--effect NAME[:CHANNEL], repeatable (each occurrence adds effects; a comma list is several)."""
    p.add_argument(
        "--effect",
        action="extend",
        type=_effect_list,
        default=None,
        metavar="NAME[:CHANNEL]",
        help="make an effect part of the model, free at its null (repeatable; "
        "'fdml effects' lists them), e.g. --effect time_delay:alpha --effect sensor_offset:az",
    )


def _effect_list(text: str) -> list[str]:
    """``time_delay:alpha`` -> [it]; ``a:x,b`` splits at commas that start a new effect name.

    A channel list such as ``structural_mode:q,az`` stays one effect: a comma
    piece without ':' or '@' after one with a channel continues that channel.
    """
    out: list[str] = []
    for piece in (x.strip() for x in text.split(",")):
        if not piece:
            continue
        if (
            out
            and ("@" in out[-1] or ":" in out[-1])
            and ":" not in piece
            and "@" not in piece
            and piece in ("alpha", "q", "az", "a_z", "de", "alpha_w", "tail")
        ):
            out[-1] = f"{out[-1]},{piece}"
        else:
            out.append(piece)
    return out


def make_model_from_args(args, values: dict | None = None):
    """Build the model named by the arguments, with ``values`` set (no records: see :func:`model_for_records`)."""
    return model_for_records(args, (), values)[0]


def model_for_records(args, records, values: dict | None = None):
    """(model, provenance) by the model rule of :mod:`fdml.commands._options`.

    Without ``--model``: unsteady with ``--aircraft``, else dimensional, whose
    airspeed is ``--airspeed`` or else the records' mean airspeed.
    ``provenance`` says where the airspeed came from (``--airspeed``,
    ``aircraft`` or ``record``) and lists the flight condition the records
    carry (:func:`fdml.conditions.record_conditions`).
    """
    from ..aircraft import aircraft_for_lags, lag_provenance
    from ..conditions import record_airspeed, record_conditions
    from ..errors import ParameterError
    from ..models import make_model

    kind = default_model(args)
    opts: dict = {"gust": bool(args.gust)}
    if args.airspeed is not None:
        opts["airspeed"] = args.airspeed
    source = "--airspeed" if args.airspeed is not None else "aircraft"
    if kind == "dimensional" and args.aircraft is None and args.airspeed is None:
        U = record_airspeed(records)
        if U is None:
            raise ParameterError(
                "the dimensional model needs --airspeed U (m/s) or --aircraft"
                + (", or a record that carries its airspeed" if records else "")
            )
        opts["airspeed"], source = U, "record"
    elif kind != "dimensional":
        if args.aircraft is None:
            raise ParameterError(f"the {kind} model needs --aircraft NAME or FILE.json")
        if args.airspeed is not None:
            raise ParameterError(
                f"--airspeed applies to the dimensional model; the {kind} model takes the airspeed of --aircraft"
            )
        opts.pop("airspeed", None)
    aircraft = args.aircraft
    if kind == "unsteady":  # freeing a lag constant is a way out of the missing-lag refusal (fdml.aircraft)
        aircraft = aircraft_for_lags(aircraft, getattr(args, "free", None))
    model = make_model(kind, aircraft, **opts)
    effects = list(getattr(args, "effect", None) or ())
    if effects:
        model = model.with_effects(effects)
    if values:
        model.parameters.check_names(values)
        model = model.with_values(values)
    provenance = {
        "model": {"kind": kind, "source": "--model" if getattr(args, "model", None) else "model rule"},
        "airspeed": {"value": float(model.U), "unit": "m/s", "source": source},
    }
    if kind == "unsteady":
        provenance["lag_constants"] = lag_provenance(aircraft)
    cond = record_conditions(records)
    if cond:
        provenance["record_conditions"] = cond
    return model, provenance


def model_spec_from_args(args, **fields):
    """The :class:`fdml.batch.ModelSpec` named by the arguments (batch, montecarlo), effects included.

    The model rule of :func:`model_for_records`, without records (the
    dimensional model needs ``--airspeed`` or ``--aircraft``).  The effects are
    resolved here, so a bad name fails before any work.
    """
    from ..batch import ModelSpec
    from ..errors import FdmlError

    kind = default_model(args)
    if kind == "dimensional" and args.aircraft is None and args.airspeed is None:
        raise FdmlError("the dimensional model needs --airspeed U (m/s) or --aircraft")
    if kind != "dimensional" and args.aircraft is None:
        raise FdmlError(f"the {kind} model needs --aircraft NAME or FILE.json")
    options = {"gust": bool(args.gust)}
    if args.airspeed is not None:
        options["airspeed"] = args.airspeed
    spec = ModelSpec(
        kind=kind, aircraft=args.aircraft, options=options, effects=tuple(getattr(args, "effect", None) or ()), **fields
    )
    spec.build()  # an unknown effect, parameter or option: one line now, not once per record
    return spec


def check_band_option(text, option: str = "--band", *, positive: bool = True) -> None:
    """Refuse a malformed or unusable band before any work (fdml's one band check).

    ``montecarlo`` and ``batch`` would otherwise fail every run one by one and
    print a table of NaN; the message names ``option``.
    """
    from ..spectral import parse_band

    parse_band(text, what=option, positive=positive)


def _integer(text: str, lowest: int, what: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer, got {text!r}") from None
    if value < lowest:
        raise argparse.ArgumentTypeError(f"must be {what}, got {value}")
    return value


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1 (counts of workers, runs); usage error (exit 2) otherwise."""
    return _integer(text, 1, "a positive integer")


def seed_int(text: str) -> int:
    """argparse type: a random seed, an integer >= 0 (numpy's SeedSequence refuses negative seeds)."""
    return _integer(text, 0, "a non-negative integer (numpy seeds cannot be negative)")
