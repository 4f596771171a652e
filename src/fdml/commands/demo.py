"""``fdml demo``: the main job on a bundled default (WK Table 1, Navion)."""

from __future__ import annotations


def register(sub) -> None:
    p = sub.add_parser("demo", help="simulate a Navion 3-2-1-1, fit steady and unsteady, "
                       "print the table and write a Bode figure")
    p.add_argument("-o", "--out", default="fdml-demo", help="output folder (default ./fdml-demo)")
    p.add_argument("--seed", type=int, default=1, help="noise seed (default 1)")
    p.add_argument("--noise", type=float, default=0.02,
                   help="noise std as a fraction of each output's RMS (default 0.02)")
    p.add_argument("--no-figure", action="store_true", help="skip the figure (no matplotlib)")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..cli import print_json
    from ..demo import run_demo

    res = run_demo(args.out, seed=args.seed, noise=args.noise, figure=not args.no_figure)
    if args.json:
        print_json({"comparison": {k: v for k, v in res.comparison.to_dict().items() if k != "fits"},
                    "files": {k: str(v) for k, v in res.files.items()}})
        return 0
    print("fdml demo: Navion 3-2-1-1 simulated with the unsteady model "
          f"({100 * args.noise:g} % noise, seed {args.seed}); steady = six-derivative model\n")
    print(res.table)
    print()
    for k, v in res.files.items():
        print(f"wrote {k:9s} {v}")
    return 0
