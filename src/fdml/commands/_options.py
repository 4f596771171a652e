"""One option spec for every command: shared argument groups.

Every command takes its shared options from here, so an option has one
spelling, one meaning and one help text everywhere (``tests/test_cli_options.py``
checks that over every parser).  Rules:

* defaults are ``None``: the library's default applies (or, where a command
  needs one, the command resolves it and its ``--help`` says which);
* an option that can be given several times accumulates (``action="extend"``
  or ``"append"``): ``--fix A=1 --fix B=2`` fixes both;
* no hidden spellings: an option has the one spelling ``--help`` shows.

``--noise`` means measurement noise added to simulated records everywhere it
is shown (demo, simulate, montecarlo): a fraction of each output's RMS, or
absolute standard deviations ``alpha=..,q=..,az=..``.  The likelihood's noise
model of ``fdml diagnose`` is ``--noise-model``.

The model rule, stated in ``--help`` of every command with ``--model``: without
``--model``, the model is ``unsteady`` when ``--aircraft`` is given, else
``dimensional`` with the airspeed from ``--airspeed`` or, for commands that
read records, the record's mean airspeed.

Kept free of heavy imports: ``fdml --help`` builds every parser.
"""

from __future__ import annotations

import argparse

from ..fit_options import command_line_options, parse_outputs
from ..models import MODEL_KINDS
from ..spectral import DEFAULT_BAND, DEFAULT_STEP
from ._common import add_effect_argument, default_model, positive_int

__all__ = [
    "DEFAULT_BAND_TEXT",
    "DEFAULT_STEP_TEXT",
    "MODEL_CHOICES",
    "MODEL_RULE",
    "accumulating",
    "add_band_option",
    "add_fit_options",
    "add_json_option",
    "add_model_options",
    "add_noise_option",
    "add_output_option",
    "add_progress_option",
    "add_record_options",
    "add_set_option",
    "add_strict_option",
    "add_workers_option",
    "default_model",
    "fit_kwargs",
    "progress_wanted",
]


#: Model names, from :data:`fdml.models.MODEL_KINDS` (the one list).
MODEL_CHOICES = tuple(MODEL_KINDS)
#: The default band ``LO:HI:STEP`` (rad/s), from :data:`fdml.spectral.DEFAULT_BAND`.
DEFAULT_BAND_TEXT = ":".join(f"{x:g}" for x in DEFAULT_BAND)
#: The step of a band given as ``LO:HI`` (rad/s), from :data:`fdml.spectral.DEFAULT_STEP`.
DEFAULT_STEP_TEXT = f"{DEFAULT_STEP:g}"
#: The one rule for the model when --model is not given (quoted in --help).
MODEL_RULE = "unsteady with --aircraft, else dimensional with --airspeed or the record's mean airspeed"
#: The same rule for commands that read no record (simulate, response, montecarlo, design).
MODEL_RULE_NO_RECORD = "unsteady with --aircraft, else dimensional with --airspeed"


#: The two kinds of --gust (:func:`add_model_options`): a switch, or the turbulence simulate flies in.
_GUST: dict[str, dict] = {
    "flag": {"action": "store_true", "help": "add the vertical gust input alpha_w (the records carry it)"},
    "std": {
        "nargs": "?",
        "type": float,
        "const": 1.0,
        "metavar": "STD",
        "help": "fly in Dryden turbulence of vertical RMS STD m/s (default 1.0) with a gust model, recording alpha_w",
    },
}


def accumulating(p, *flags, **kw) -> None:
    """A repeatable list option: every occurrence adds its values (``action="extend"``, ``nargs="+"``)."""
    p.add_argument(*flags, action="extend", nargs="+", default=None, **kw)


# --- the model ---------------------------------------------------------------------------------
def add_model_options(
    p, *, gust: str = "flag", reads_records: bool = True, what: str = "model", kinds: bool = True
) -> None:
    """--aircraft, --model, --gust, --airspeed, --effect.

    ``gust``: ``"flag"`` (the model gets the gust input alpha_w), ``"std"``
    (simulate: fly in turbulence, ``--gust [STD]``) or ``""`` (no option).
    ``kinds=False``: no --model and --airspeed (compare: its models are fixed).
    """
    g = p.add_argument_group("model")
    g.add_argument(
        "--aircraft", metavar="NAME|FILE.json", help="preset (navion, sundowner, do128) or an aircraft JSON file"
    )
    rule = MODEL_RULE if reads_records else MODEL_RULE_NO_RECORD
    if kinds:
        g.add_argument("--model", choices=MODEL_CHOICES, default=None, help=f"{what} (default: {rule})")
    if gust:
        g.add_argument("--gust", default=None, **_GUST[gust])
    if kinds:
        g.add_argument(
            "--airspeed",
            type=float,
            metavar="U",
            help="airspeed, m/s, of the dimensional model without --aircraft"
            + (" (default: the record's mean airspeed, when the file carries it)" if reads_records else ""),
        )
    add_effect_argument(g)


def add_set_option(p, help: str = "parameter values") -> None:
    """--set NAME=VALUE ..., repeatable."""
    accumulating(p, "--set", metavar="NAME=VALUE", help=f"{help} (repeatable)")


# --- the band ----------------------------------------------------------------------------------
def add_band_option(p, *, help: str | None = None) -> None:
    """--band LO:HI[:STEP], rad/s (fdml's one band syntax, :func:`fdml.spectral.parse_band`).

    Without a step the step is :data:`fdml.spectral.DEFAULT_STEP`; ``help`` replaces
    the default text (diagnose, design: their own default band and use of the step).
    """
    if help is None:
        help = f"frequency band, rad/s (default {DEFAULT_BAND_TEXT}; without :STEP the step is {DEFAULT_STEP_TEXT})"
    p.add_argument("--band", metavar="LO:HI[:STEP]", default=None, help=help)


# --- outputs, parallelism, progress, json, strict ---------------------------------------------
def add_output_option(p, *, kind: str, metavar: str, help: str, required: bool = False) -> None:
    """-o/--output: where the output goes; ``kind`` ``"file"`` or ``"folder"`` is said in --help."""
    p.add_argument("-o", "--output", metavar=metavar, default=None, required=required, help=f"output {kind}: {help}")


def add_workers_option(p) -> None:
    """--workers N (local worker processes)."""
    p.add_argument(
        "--workers", type=positive_int, metavar="N", default=None, help="local worker processes (default: all cores)"
    )


def add_progress_option(p, *, default_on: bool) -> None:
    """--progress/--no-progress; None means the command's default (said in --help)."""
    p.add_argument(
        "--progress",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="progress bar on stderr (needs tqdm: pip install 'fdml[progress]'; "
        f"default {'on, off with --json' if default_on else 'off'})",
    )


def progress_wanted(args, *, default_on: bool) -> bool:
    """--progress resolved: the flag if given, else the command's default (never with --json when by default)."""
    flag = getattr(args, "progress", None)
    if flag is None:
        return default_on and not getattr(args, "json", False)
    return bool(flag)


def add_json_option(p, help: str = "machine-readable output on stdout") -> None:
    p.add_argument("--json", action="store_true", default=None, help=help)


def add_strict_option(p, help: str) -> None:
    p.add_argument("--strict", action="store_true", default=None, help=help)


def add_noise_option(p, *, default: str | None = None) -> None:
    """--noise: measurement noise added to simulated records (FRACTION of each output's RMS, or stds)."""
    tail = f" (default {default})" if default else " (default: none)"
    p.add_argument(
        "--noise",
        metavar="FRACTION|alpha=..,q=..,az=..",
        default=None,
        help="measurement noise added to the simulated outputs: a fraction of each output's RMS, "
        f"or absolute stds{tail}",
    )


def add_steady_option(p) -> None:
    """--steady: the steady model the unsteady one is compared with (fdml compare, fdml design)."""
    p.add_argument(
        "--steady",
        choices=("derivatives", "steady"),
        default="derivatives",
        help="the steady model the unsteady one is told from: six derivatives (default, as Wells-Keskar "
        "fitted them) or the quasi-steady Wells-Keskar model",
    )


# --- fit options -------------------------------------------------------------------------------
def add_fit_options(p, *, fix_free: bool = True) -> None:
    """The fit options the command line shows (defaults: fdml.fit's), from :class:`fdml.fit_options.FitOptions`.

    Each is ``--name`` (underscores as hyphens) with the table's help, choices and spellings;
    ``fix_free=False`` leaves out the repeatable --fix and --free.
    """
    g = p.add_argument_group("fit options (defaults: fdml.fit's)")
    for o in command_line_options():
        if fix_free or not o["repeat"]:
            _add_option(g, o)


def add_fit_option(p, name: str, help: str | None = None) -> None:
    """One fit option of :func:`add_fit_options` (its name in FitOptions), as there; ``help`` replaces its text."""
    o = next(o for o in command_line_options() if o["name"] == name)
    _add_option(p, o if help is None else {**o, "help": help})


def _add_option(g, o: dict) -> None:
    if o["repeat"]:
        accumulating(g, o["flag"], metavar=o["metavar"], help=o["help"])
    elif o["switch"]:
        g.add_argument(o["flag"], action="store_true", default=None, help=o["help"])
    else:
        extra = {"metavar": o["metavar"]} if "metavar" in o else {}
        g.add_argument(o["flag"], choices=o["choices"], default=None, help=o["help"], **extra)


def fit_kwargs(args) -> dict:
    """Keyword arguments of :func:`fdml.fit` from the fit options given (None: the library's default).

    --fix and --free are the commands' own (they change the model); the others map one to one.
    """
    out = {}
    for o in command_line_options():
        v = getattr(args, o["name"], None)
        if v is not None and not o["repeat"]:
            out[o["name"]] = o["values"].get(v, v)
    if out.get("outputs") is not None:
        out["outputs"] = ",".join(parse_outputs(out["outputs"], what="--outputs"))
    return out


# --- reading records ---------------------------------------------------------------------------
def add_record_options(p) -> None:
    """--format, --t0, --t1, --columns, --units, --sign, --layout, --variable, --delimiter, --no-unit-check.

    See :func:`fdml.io.cli.record_options`.
    """
    from ..io.cli import add_record_arguments

    add_record_arguments(p)
