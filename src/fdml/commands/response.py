"""``fdml response``: G(j omega) of a model, shape (outputs, inputs, frequencies)."""

from __future__ import annotations

from . import _options as O
from ._common import assignments, make_model_from_args


def register(sub) -> None:
    p = sub.add_parser(
        "response",
        help="frequency response G(jw) of a model",
        description="Frequency response of a model.  "
        "Model rule, when --model is not given: " + O.MODEL_RULE_NO_RECORD + ".",
    )
    O.add_model_options(p, reads_records=False)
    O.add_set_option(p)
    O.add_band_option(
        p,
        help=f"frequencies, rad/s (default {O.DEFAULT_BAND_TEXT}; without :STEP the step is {O.DEFAULT_STEP_TEXT}; "
        "LO may be 0)",
    )
    O.add_json_option(p)


def run(args) -> int:
    import numpy as np

    from ..cli import show
    from ..fourier import omega_band
    from ..spectral import parse_band

    model = make_model_from_args(args, assignments(args.set))
    omega = omega_band(*parse_band(args.band, what="--band", positive=False))
    G = model.frequency_response(omega)
    lines = [
        f"{model.describe()}: |G| and phase (deg)",
        "omega".rjust(8) + "".join(f"{o + '/' + i:>24s}" for o in model.outputs for i in model.inputs),
    ]
    for k, w in enumerate(omega):  # the (output, input) pairs in the order of the header
        pairs = zip(np.abs(G[:, :, k]).ravel(), np.degrees(np.angle(G[:, :, k])).ravel())
        lines.append(f"{w:8.3f}" + "".join(f"{mag:12.5g}{phase:12.2f}" for mag, phase in pairs))
    show(
        args,
        {
            "model": model.kind,
            "outputs": list(model.outputs),
            "inputs": list(model.inputs),
            "omega": omega.tolist(),
            "shape": list(G.shape),
            "real": G.real.tolist(),
            "imag": G.imag.tolist(),
        },
        "\n".join(lines),
    )
    return 0
