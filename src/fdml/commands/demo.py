"""``fdml demo``: the main job on a bundled default (WK Table 1, Navion)."""

from __future__ import annotations

from ..demo import DEFAULT_NOISE
from . import _options as O
from ._common import noise_option, seed_int

#: Where the demo writes when -o is not given.
DEFAULT_OUTPUT = "fdml-demo"


def register(sub) -> None:
    p = sub.add_parser(
        "demo", help="simulate a Navion 3-2-1-1, fit steady and unsteady, print the table and write a Bode figure"
    )
    O.add_output_option(
        p, kind="folder", metavar="DIR", help=f"the table, fits and figure (default ./{DEFAULT_OUTPUT})"
    )
    p.add_argument("--seed", type=seed_int, default=1, help="noise seed (default 1)")
    O.add_noise_option(p, default=f"{DEFAULT_NOISE:g}")
    p.add_argument("--no-figure", action="store_true", help="skip the figure (no matplotlib)")
    O.add_json_option(p)


def run(args) -> int:
    from ..cli import show
    from ..demo import run_demo
    from ..errors import FdmlError

    noise = noise_option(args.noise or str(DEFAULT_NOISE))
    if isinstance(noise, dict):
        raise FdmlError(
            "fdml demo --noise takes a fraction of each output's RMS (e.g. 0.02); "
            "absolute stds go to fdml simulate --noise"
        )
    res = run_demo(args.output or DEFAULT_OUTPUT, seed=args.seed, noise=noise, figure=not args.no_figure)
    evidence = res.comparison.evidence
    assert evidence is not None  # the demo's fits hold their spectra
    header = (
        "fdml demo: Navion 3-2-1-1 simulated with the unsteady model "
        f"({100 * noise:g} % noise, seed {args.seed}); steady = six-derivative model\n"
    )
    show(
        args,
        {
            "comparison": {
                "unsteady": _set_dict(res.comparison.unsteady_set),
                "steady": _set_dict(res.comparison.steady_set),
                "shifts": res.comparison.shifts,
                "evidence": evidence.to_dict(),
            },
            "files": {k: str(v) for k, v in res.files.items()},
        },
        "\n".join(
            [
                header,
                res.table,
                "",
                "evidence: " + evidence.text(),
                "",
                *(f"wrote {k:9s} {v}" for k, v in res.files.items()),
            ]
        ),
    )
    return 0


def _set_dict(derivatives: dict) -> dict:
    """``{name: (value, stderr)}`` as ``{name: {"value", "stderr"}}``."""
    return {k: {"value": v, "stderr": e} for k, (v, e) in derivatives.items()}
