"""``fdml design``: plan the manoeuvre: an optimised input, its predicted bounds, steady-vs-unsteady power."""

from __future__ import annotations

import math

from ..errors import ParameterError
from . import _options as O
from ._common import assignments, make_model_from_args, noise_option

_CRITERIA = ("d-optimal", "a-optimal", "discriminate")


def _angle(text: str | None, what: str, rate: bool = False) -> float | None:
    """'3deg', '0.05' (rad) or, for a rate, '40deg/s', '0.7' (rad/s)."""
    if text is None:
        return None
    t = text.strip().lower()
    unit = "deg/s" if rate else "deg"
    deg = t.endswith(unit)
    if rate and not deg and t.endswith("/s"):
        t = t[:-2]
    num = t[: -len(unit)] if deg else t.removesuffix("rad")
    try:
        v = float(num)
    except ValueError:
        raise ParameterError(f"{what} {text!r}: give a number in rad{'/s' if rate else ''} or e.g. 3{unit}") from None
    v = math.radians(v) if deg else v
    if not (math.isfinite(v) and v > 0):
        raise ParameterError(f"{what} {text!r} must be positive and finite")
    return v


def register(sub) -> None:
    p = sub.add_parser(
        "design",
        help="design a manoeuvre: optimised input, predicted bounds, steady-vs-unsteady detection",
        description="Design an elevator input before the flight (or assess one with --input): predicted "
        "standard errors from the estimator's own bound, the gain over a 3-2-1-1 and a sweep of the same "
        "duration and peak, and the probability that the unsteady model is told from the steady one.  "
        "Model rule, when --model is not given: " + O.MODEL_RULE_NO_RECORD + ".",
    )
    O.add_model_options(p, gust="flag", reads_records=False)
    O.add_set_option(p)
    p.add_argument("--criterion", choices=_CRITERIA, default="d-optimal", help="design criterion (default d-optimal)")
    p.add_argument("--targets", metavar="NAME,...", help="parameters of the a-optimal criterion, e.g. b1,y_w,G")
    O.accumulating(p, "--free", metavar="NAME", help="free further parameters, e.g. b1 of a gust model (repeatable)")
    p.add_argument("--duration", type=float, default=20.0, help="record length, s (default 20)")
    p.add_argument("--dt", type=float, default=0.02, help="sample interval, s (default 0.02)")
    p.add_argument("--amplitude", default="1deg", help="peak elevator, rad or e.g. 3deg (default 1deg)")
    p.add_argument("--rate", help="elevator rate limit, rad/s or e.g. 40deg/s (default none)")
    O.add_band_option(
        p,
        help=f"band of the input and the fit, rad/s (default 0.5:10; without :STEP the step is {O.DEFAULT_STEP_TEXT})",
    )
    O.add_noise_option(p, default="0.05, of the 3-2-1-1 response")
    O.add_steady_option(p)
    p.add_argument("--level", type=float, default=0.05, help="test level of the detection probability (default 0.05)")
    O.accumulating(
        p,
        "--detect",
        metavar="EFFECT",
        help="report the minimum detectable value of a library effect with the input, e.g. time_delay:alpha "
        "(repeatable; 'fdml effects' lists them)",
    )
    p.add_argument(
        "--refine",
        type=int,
        default=40,
        metavar="N",
        help="full evaluations of the criterion that refine the optimised spectrum (default 40; 0: none)",
    )
    p.add_argument("--input", metavar="FILE.csv", help="predict for this input (t, de) instead of designing one")
    O.add_output_option(
        p, kind="file", metavar="INPUT.csv", help="the designed input (t, de), and a figure beside it (.png)"
    )
    O.add_json_option(p)


def _names(items) -> list[str]:
    """'a,b' or ['a', 'b,c'] -> ['a', 'b', 'c']."""
    items = [items] if isinstance(items, str) else list(items or [])
    return [x.strip() for item in items for x in item.split(",") if x.strip()]


def run(args) -> int:
    from pathlib import Path

    from ..cli import show
    from ..design import design, plot_design, read_input
    from ..outputs import StagedOutputs, check_output

    if args.input is None and args.output is None:
        raise ParameterError("fdml design needs -o INPUT.csv for the designed input (or --input FILE.csv)")
    figure = None
    if args.output is not None:
        check_output(args.output, [args.input, args.aircraft], what="input file")  # before any work
        figure = Path(args.output).with_suffix(".png")
        check_output(figure, [args.input, args.aircraft], what="figure")
    model = make_model_from_args(args, assignments(args.set))
    given = read_input(args.input) if args.input else None
    amplitude = float(max(abs(given.de))) if given is not None else _angle(args.amplitude, "--amplitude")
    assert amplitude is not None  # --amplitude has a default
    rate = _angle(args.rate, "--rate", rate=True)
    d = design(
        model,
        criterion=args.criterion,
        duration=args.duration,
        amplitude=amplitude,
        band=args.band,
        dt=args.dt,
        rate=math.inf if rate is None else rate,
        targets=_names(args.targets),
        steady=args.steady,
        level=args.level,
        given=given,
        free=_names(args.free),
        refine=max(args.refine, 0),
        detect=_names(args.detect),
        **({} if args.noise is None else {"noise": noise_option(args.noise)}),  # the library's default 0.05
    )
    if args.output is not None:
        with StagedOutputs([args.input, args.aircraft]) as out:
            out.write_text(args.output, d.input.to_record().to_csv_text(), what="input file")
            out.savefig(lambda: plot_design(d), figure, dpi=110)
    show(
        args,
        {**d.to_dict(args.output if args.output is not None else args.input), "figure": figure and str(figure)},
        d.table() + ("" if figure is None else f"\n\nwrote {args.output} (t, de) and {figure}"),
    )
    return 0
