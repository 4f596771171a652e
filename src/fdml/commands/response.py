"""``fdml response``: G(j omega) of a model, shape (outputs, inputs, frequencies)."""

from __future__ import annotations

from ._common import add_model_arguments, assignments, make_model_from_args


def register(sub) -> None:
    p = sub.add_parser("response", help="frequency response G(jw) of a model")
    add_model_arguments(p)
    p.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE", help="parameter values")
    p.add_argument("--omega", default="0.1:10:0.1", metavar="LO:HI:STEP", help="frequencies, rad/s")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=run)


def run(args) -> int:
    import numpy as np

    from ..fourier import omega_band
    from ..spectra import parse_band

    model = make_model_from_args(args, assignments(args.set))
    omega = omega_band(*parse_band(args.omega, what="--omega", positive=False))
    G = model.frequency_response(omega)
    if args.json:
        from ..cli import print_json

        print_json({"model": model.kind, "outputs": list(model.outputs), "inputs": list(model.inputs),
                    "omega": omega.tolist(), "shape": list(G.shape),
                    "real": G.real.tolist(), "imag": G.imag.tolist()})
        return 0
    print(f"{model.describe()}: |G| and phase (deg)")
    head = "omega".rjust(8) + "".join(f"{o + '/' + i:>24s}" for o in model.outputs for i in model.inputs)
    print(head)
    for k, w in enumerate(omega):
        row = "".join(f"{abs(G[a, b, k]):12.5g}{np.degrees(np.angle(G[a, b, k])):12.2f}"
                      for a in range(G.shape[0]) for b in range(G.shape[1]))
        print(f"{w:8.3f}{row}")
    return 0
