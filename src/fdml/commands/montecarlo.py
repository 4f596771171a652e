"""``fdml montecarlo``: bias, scatter and scatter/CRB of the estimator over N seeded simulations."""

from __future__ import annotations

from ..outputs import atomic_savefig, atomic_write_text, check_output_folder
from . import _options as O
from ._common import assignments, check_band_option, model_spec_from_args, noise_option, seed_int

#: Noise when --noise is not given: a fraction of each output's RMS.
DEFAULT_NOISE = "0.03"
#: Files written into the -o folder.
FILES = {"json": "montecarlo.json", "table": "montecarlo.txt", "figure": "montecarlo.png"}


def register(sub) -> None:
    p = sub.add_parser(
        "montecarlo",
        help="Monte Carlo study: fit N seeded noisy simulations, "
        "bias, scatter and efficiency (scatter/CRB) per parameter",
        description="Monte Carlo study.  --model is the truth model (simulated, and fitted unless "
        "--fit-model names another); "
        "model rule, when --model is not given: " + O.MODEL_RULE_NO_RECORD + ".",
    )
    O.add_model_options(p, reads_records=False, what="truth model, simulated and fitted")
    O.add_set_option(p, "truth parameter values")
    p.add_argument("-n", type=int, default=1000, metavar="N", help="number of runs (default 1000)")
    p.add_argument(
        "--fit-model",
        choices=O.MODEL_CHOICES,
        default=None,
        help="a different model to fit to the truth model's records (default: the truth model)",
    )
    p.add_argument("--maneuver", default="3211", choices=("3211", "doublet", "multisine"))
    p.add_argument("--duration", type=float, default=10.0, help="record length, s (default 10)")
    p.add_argument("--dt", type=float, default=0.02, help="sample interval, s (default 0.02)")
    O.add_noise_option(p, default=DEFAULT_NOISE)
    p.add_argument("--seed", type=seed_int, default=0, help="seed (default 0)")
    O.add_band_option(p)
    O.add_workers_option(p)
    p.add_argument("--scheduler", metavar="ADDRESS", help="run on a Dask cluster (needs the 'dask' extra)")
    O.add_progress_option(p, default_on=True)
    O.add_output_option(
        p, kind="folder", metavar="DIR", help="DIR/montecarlo.json, DIR/montecarlo.txt and DIR/montecarlo.png"
    )
    O.add_json_option(p)


def run(args) -> int:
    import importlib.util
    from pathlib import Path

    from ..batch import ModelSpec
    from ..cli import show
    from ..montecarlo import monte_carlo

    truth = model_spec_from_args(args, values=assignments(args.set))
    fit_model = None
    if args.fit_model and args.fit_model != truth.kind:
        fit_model = ModelSpec(kind=args.fit_model, aircraft=args.aircraft, options=truth.options, effects=truth.effects)
    noise = noise_option(args.noise or DEFAULT_NOISE)
    check_band_option(args.band)  # up front: a bad band would fail all N runs one by one
    paths = {k: Path(args.output or ".") / name for k, name in FILES.items()}
    if args.output:  # before any work: the folder and its three files
        check_output_folder(args.output, dict.fromkeys(FILES.values(), "output file"), [args.aircraft])
    res = monte_carlo(
        truth,
        n=args.n,
        maneuver=args.maneuver,
        duration=args.duration,
        dt=args.dt,
        noise=noise,
        seed=args.seed,
        fit_model=fit_model,
        fit_kwargs={} if args.band is None else {"band": args.band},
        engine=args.scheduler or "process",
        workers=args.workers,
        progress=True if O.progress_wanted(args, default_on=True) and importlib.util.find_spec("tqdm") else None,
    )
    if args.output:
        res.to_json(paths["json"])
        atomic_write_text(paths["table"], res.table() + "\n")
        if not importlib.util.find_spec("matplotlib"):
            del paths["figure"]
        else:
            atomic_savefig(lambda: res.plot()[0], paths["figure"], dpi=120)
    files = {k: str(v) for k, v in paths.items()} if args.output else {}
    summary = {"n": res.n, "used": res.n_used, "failed": len(res.errors), "wall_time": res.wall_time}
    show(
        args,
        {**summary, "settings": res.settings, "stats": res.stats(), "files": files},
        "\n".join([res.table(), *(f"wrote {f}" for f in files.values())]),
    )
    return 0 if res.n_used >= 2 else 1
