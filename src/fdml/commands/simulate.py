"""``fdml simulate``: a simulated flight record from a model, as CSV."""

from __future__ import annotations

from . import _options as O
from ._common import assignments, make_model_from_args, noise_option, seed_int


def register(sub) -> None:
    p = sub.add_parser(
        "simulate",
        help="simulate a manoeuvre with a model and write a CSV record",
        description="Simulate a manoeuvre.  Model rule, when --model is not given: " + O.MODEL_RULE_NO_RECORD + ".",
    )
    O.add_model_options(p, gust="std", reads_records=False)
    O.add_set_option(p)
    p.add_argument("--maneuver", default="3211", choices=("3211", "doublet", "multisine"))
    p.add_argument("--amplitude", type=float, help="elevator amplitude, rad")
    p.add_argument("--duration", type=float, default=10.0, help="record length, s (default 10)")
    p.add_argument("--dt", type=float, default=0.02, help="sample interval, s (default 0.02)")
    O.add_noise_option(p)
    p.add_argument("--outputs", help="outputs to simulate beyond alpha,q,az, comma-separated: theta, qdot")
    p.add_argument("--seed", type=seed_int, help="random seed (an integer >= 0)")
    O.add_output_option(p, kind="file", metavar="RECORD.csv", required=True, help="the simulated record (CSV)")
    O.add_json_option(p)


def run(args) -> int:
    from ..cli import show
    from ..outputs import check_output
    from ..simulate import simulate_maneuver

    check_output(args.output, [args.aircraft], what="record file")  # before any work
    model = make_model_from_args(args, assignments(args.set)).with_outputs(args.outputs or ())
    rec = simulate_maneuver(
        model,
        args.maneuver,
        duration=args.duration,
        dt=args.dt,
        gust_std=args.gust or 0.0,
        seed=args.seed,
        noise=noise_option(args.noise),  # a number is a fraction of RMS in simulate_maneuver too
        **({} if args.amplitude is None else {"amplitude": args.amplitude}),  # simulate_maneuver's default
    )
    rec.to_csv(args.output)
    show(
        args,
        {"output": args.output, "samples": rec.n, "dt": rec.dt, "model": model.kind, "signals": list(rec.signals)},
        f"wrote {args.output}: {rec.n} samples at {rec.dt:g} s, signals {', '.join(rec.signals)}",
    )
    return 0
