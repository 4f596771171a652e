"""Argument helpers shared by the commands (no heavy imports here)."""

from __future__ import annotations

import argparse
import math

from ..errors import ParameterError, RecordError


def default_model(args) -> str:
    """The model kind by the one rule: --model, else unsteady with --aircraft, else dimensional."""
    if getattr(args, "model", None):
        return args.model
    return "unsteady" if getattr(args, "aircraft", None) is not None else "dimensional"


def assignments(items, what: str = "NAME=VALUE") -> dict[str, float]:
    """Parse ``["Cm_de=-1.4", ...]`` into ``{"Cm_de": -1.4}``."""
    out: dict[str, float] = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep or not name:
            raise ParameterError(f"expected {what}, got {item!r}")
        try:
            number = float(value)
        except ValueError:
            raise ParameterError(f"{item!r}: {value!r} is not a number") from None
        if not math.isfinite(number):  # float() reads nan and inf: no parameter value is either
            raise ParameterError(f"{item!r}: {value.strip()!r} is not a finite number")
        if out.get(name, number) != number:
            raise ParameterError(f"{item!r}: {name} is already given as {out[name]:g}")
        out[name] = number
    return out


def noise_option(text: str | None):
    """``--noise``: ``0.02`` (a fraction of each output's RMS) or ``alpha=1e-3,q=2e-3,az=0.01`` (stds); None: not given.

    The level is checked by :func:`fdml.record.check_noise`, the library's one check.
    """
    if text is None:
        return None
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
        if out and ("@" in out[-1] or ":" in out[-1]) and piece in ("alpha", "q", "az", "a_z", "de", "alpha_w", "tail"):
            out[-1] = f"{out[-1]},{piece}"
        else:
            out.append(piece)
    return out


def fit_spectra(records, band, kwargs: dict):
    """The records' spectra for :func:`fdml.fit`: the front end's ``trim`` moves out of ``kwargs`` (fit options).

    The rows are the fit's ``outputs``.  One record gives its FrequencyData,
    several give a list (a joint fit).
    """
    from ..spectral import spectra

    given: dict = {"outputs": kwargs.get("outputs")}
    if "trim" in kwargs:
        given["trim"] = kwargs.pop("trim")
    data = [spectra(r, band=band, **given) for r in records]
    return data if len(data) > 1 else data[0]


def make_model_from_args(args, values: dict | None = None):
    """Build the model named by the arguments, with ``values`` set (no records: see :func:`model_for_records`)."""
    return model_for_records(args, (), values)[0]


def model_for_records(args, records, values: dict | None = None):
    """(model, provenance) by the model rule of :mod:`fdml.commands._options`.

    Without ``--model``: unsteady with ``--aircraft``, else dimensional, whose
    airspeed is ``--airspeed`` or else the records' mean airspeed
    (:func:`fdml.conditions.airspeed_rule`).  ``provenance`` says where the
    airspeed came from (``--airspeed``, ``aircraft`` or ``record``) and lists
    the flight condition the records carry (:func:`fdml.conditions.model_provenance`).
    """
    from ..aircraft import aircraft_for_lags
    from ..conditions import airspeed_rule, model_provenance
    from ..models import make_model, with_effects

    kind = default_model(args)
    check_model_rule(kind, args, bool(records), records)
    opts: dict = {"gust": bool(args.gust)}
    U, source = airspeed_rule(kind, args.aircraft, args.airspeed, records)
    if U is not None:
        opts["airspeed"] = U
    aircraft = args.aircraft
    if kind == "unsteady":  # lag constants by --set, --fix or --free count as given (fdml.aircraft.aircraft_for_lags)
        for option, supplied in (("--fix", assignments(getattr(args, "fix", None))), ("--set", values)):
            aircraft = aircraft_for_lags(aircraft, given=supplied, source=option)
        aircraft = aircraft_for_lags(aircraft, getattr(args, "free", None))
    model = make_model(kind, aircraft, **opts)
    if getattr(args, "effect", None):
        model = with_effects(model, list(args.effect))
    if values:
        model.parameters.check_names(values)
        model = model.with_values(values)
    model_source = "--model" if getattr(args, "model", None) else "model rule"
    return model, model_provenance(kind, model_source, model, "--airspeed" if source == "given" else source, records)


def check_model_rule(kind: str, args, reads_records: bool, records=None) -> None:
    """Refuse, in one line, a model the arguments cannot make: no airspeed, no aircraft, a misplaced --airspeed.

    ``records``: when given, the dimensional model without --airspeed and --aircraft
    needs them to carry their airspeed.
    """
    from ..conditions import record_airspeed

    if kind == "dimensional" and args.aircraft is None and args.airspeed is None:
        if not reads_records or (records is not None and record_airspeed(records) is None):
            raise ParameterError(
                "the dimensional model needs --airspeed U (m/s) or --aircraft"
                + (", or a record that carries its airspeed" if reads_records else "")
            )
    elif kind != "dimensional":
        if args.aircraft is None:
            raise ParameterError(f"the {kind} model needs --aircraft NAME or FILE.json")
        if args.airspeed is not None:
            raise ParameterError(
                f"--airspeed applies to the dimensional model; the {kind} model takes the airspeed of --aircraft"
            )


def model_spec_from_args(args, *, reads_records: bool = False, **fields):
    """The :class:`fdml.batch.ModelSpec` named by the arguments (batch, montecarlo), effects included.

    The model rule of :func:`model_for_records`; with ``reads_records`` (batch),
    the dimensional model without ``--airspeed`` and ``--aircraft`` takes each
    record's mean airspeed when it is fitted.  The effects are resolved here,
    so a bad name fails before any work.
    """
    from ..batch import ModelSpec

    kind = default_model(args)
    check_model_rule(kind, args, reads_records)
    options = {"gust": bool(args.gust)}
    if args.airspeed is not None:
        options["airspeed"] = args.airspeed
    spec = ModelSpec(
        kind=kind, aircraft=args.aircraft, options=options, effects=tuple(getattr(args, "effect", None) or ()), **fields
    )
    spec.check()  # an unknown effect, parameter or option: one line now, not once per record
    return spec


def check_band_option(text) -> None:
    """Refuse a malformed or unusable ``--band`` before any work (fdml's one band check).

    ``montecarlo`` and ``batch`` would otherwise fail every run one by one and
    print a table of NaN.
    """
    from ..spectral import parse_band

    parse_band(text, what="--band", positive=True)


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
