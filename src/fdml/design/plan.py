"""One call that plans a manoeuvre: the optimised input, its predicted bounds, the baselines, discrimination.

All inputs compared see the same sensor: a noise given as a fraction of
output RMS is turned into standard deviations once, from the response to the
3-2-1-1 of the same peak amplitude, and those stds are used for every input.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import FdmlError, ParameterError
from ..jsoncodec import Fields
from ..models import make_model
from ..spectral import parse_band
from .discrimination import Detectable, Discrimination, discriminate, minimum_detectable
from .inputs import DesignInput, Limits, classic_input, read_input
from .optimize import CRITERIA, optimal_input
from .prediction import Prediction, noise_stds, predict, response

__all__ = ["Design", "design", "BASELINES"]

#: The classic inputs an optimised one is compared with (same duration and peak).
BASELINES = ("3211", "sweep")


@dataclass(frozen=True)
class Design:
    """A planned manoeuvre.

    Parameters
    ----------
    criterion : str
        ``d-optimal``, ``a-optimal``, ``discriminate`` or ``given`` (an input from a file).
    input : DesignInput
        The optimised (or given) input.
    predicted : Prediction
        Its predicted bounds.
    baselines : dict
        ``{name: Prediction}`` of the classic inputs of equal duration and peak.
    discrimination : dict
        ``{name: Discrimination}`` for the input and each baseline (unsteady models only).
    noise : dict
        Measurement-noise stds used for every input (rad, rad/s, g).
    band : tuple
        The fit's band (lo, hi, step), rad/s.
    detectable : tuple of Detectable
        Minimum detectable value of each parameter of the effects asked for, with the input.
    placeholders : dict, optional
        Model parameter -> the generic value it stands on, for each value that
        neither the aircraft file nor the user gave (:meth:`fdml.models.Model.placeholders`):
        the predictions hold for those values, not for the aircraft.
    """

    criterion: str
    input: DesignInput
    predicted: Prediction
    baselines: dict = field(default_factory=dict)
    discrimination: dict = field(default_factory=dict)
    noise: dict = field(default_factory=dict)
    band: tuple = ()
    detectable: tuple = ()
    placeholders: dict = field(default_factory=dict)

    def gains(self) -> dict[str, dict[str, float]]:
        """Ratio of each baseline's predicted stderr to the input's, per model parameter (> 1: a gain).

        Returns
        -------
        dict
            ``{baseline: {parameter: ratio}}``.
        """
        se = self.predicted.to_dict()
        return {
            b: {n: p.to_dict()[n]["stderr"] / se[n]["stderr"] for n in se if n in p.to_dict()}
            for b, p in self.baselines.items()
        }

    def table(self) -> str:
        """Plain-text table: value and predicted stderr per parameter, input and baselines; discrimination.

        Returns
        -------
        str
            The table, with minimum detectable values and discrimination where present.
        """
        names = list(self.predicted.to_dict())
        cols = {self.input.name: self.predicted, **self.baselines}
        w = max(20, *(len(c) + 2 for c in cols))  # every column as wide as its input's name
        head = f"{'parameter':<12}{'value':>11}" + "".join(f"{c:>{w}}" for c in cols)
        lines = [head, "-" * len(head)]
        for n in names:
            mark = "*" if n in self.placeholders else " "
            row = f"{n:<12}{self.predicted.values[n]:>10.4g}{mark}"
            row += "".join(f"{p.stderr.get(n, math.nan):>{w}.3g}" for p in cols.values())
            lines.append(row)
        lines += _placeholder_note(self.placeholders, len(head))
        if self.detectable:
            lines += ["", f"{'effect':<22}{'parameter':<12}{'min. detectable':>22}  (power, level)"]
            for e in self.detectable:
                value = f"{e.minimum:.4g} {e.unit}".rstrip()
                lines.append(f"{e.effect:<22}{e.parameter:<12}{value:>22}  ({e.power:g}, {e.level:g})")
        if self.discrimination:
            head = f"{'steady vs unsteady':<22}{'lambda':>10}{'P(detect)':>11}{'P(favoured)':>13}{'P(compare)':>12}"
            lines += ["", head]
            for k, d in self.discrimination.items():
                row = f"{d.noncentrality:>10.3g}{d.probability:>11.3f}{d.favoured:>13.3f}{d.vuong:>12.3f}"
                lines.append(f"{k[:22]:<22}{row}")
        return "\n".join(lines)

    def to_dict(self, csv_path=None) -> dict:
        """JSON-ready: ``input`` (the CSV path), ``predicted`` (with ``baselines``), ``discrimination``.

        Parameters
        ----------
        csv_path : str or Path, optional
            Where the input's CSV was written (``input`` is None without it).

        Returns
        -------
        dict
            The plan as plain JSON data.
        """
        predicted = {
            "input": self.input.name,
            "parameters": self.predicted.to_dict(),
            "baselines": {k: p.to_dict() for k, p in self.baselines.items()},
            "gains": self.gains(),
        }
        return {
            "input": None if csv_path is None else str(csv_path),
            "criterion": self.criterion,
            "limits": self.input.report(),
            "band": list(self.band),
            "noise": self.noise,
            "predicted": predicted,
            "discrimination": {k: d.to_dict() for k, d in self.discrimination.items()},
            "detectable": [e.to_dict() for e in self.detectable],
            "placeholders": dict(self.placeholders),
        }

    @classmethod
    def from_dict(cls, d, *, input: DesignInput | None = None, source: str = "fdml design") -> Design:
        """Inverse of :meth:`to_dict`, as far as it goes; a bad key raises a one-line FdmlError naming ``source``.

        Restored: the criterion, band, noise, discrimination, minimum
        detectable values and, for the input and each baseline, the model
        parameters' values and predicted standard errors
        (:meth:`Prediction.from_dict`: no correlations).  :meth:`to_dict` does
        not write the input history, only the CSV file that holds it
        (``input``): the history is ``input`` when given, else read from that
        file (:func:`~fdml.design.inputs.read_input`, its limits taken from
        the history itself: the planning limits are not written), named as
        saved.  A plan written without its CSV needs ``input``.  The
        baselines' histories are not written: their predictions have no input.
        ``limits`` and ``gains`` are derived, not read.

        Parameters
        ----------
        d : dict
            As written by :meth:`to_dict`.
        input : DesignInput, optional
            The input history (default: read from the CSV file ``d["input"]`` names).
        source : str, optional
            What ``d`` came from, for the message.

        Returns
        -------
        Design
            The plan.
        """
        f = Fields(d, source)
        pred = f.sub("predicted")
        name = pred.string("input")
        inp = _saved_input(f, name) if input is None else input
        noise = f.number_map("noise")
        params, bases = pred.raw("parameters"), pred.sub("baselines")
        return cls(
            criterion=f.string("criterion", choices=(*CRITERIA, "given")),
            input=inp,
            predicted=Prediction.from_dict(params, noise=noise, input=inp, source=f"{source}: predicted.parameters"),
            baselines={
                k: Prediction.from_dict(bases.raw(k), noise=noise, source=f"{source}: predicted.baselines.{k}")
                for k in bases.doc
            },
            discrimination={
                k: Discrimination.from_dict(v, source=f"{source}: discrimination.{k}")
                for k, v in f.mapping("discrimination").items()
            },
            noise=noise,
            band=f.numbers("band", length=3),
            detectable=tuple(
                Detectable.from_dict(x.doc, source=f"{source}: detectable[{i}]")
                for i, x in enumerate(f.items("detectable"))
            ),
            placeholders=_string_map(f, "placeholders"),
        )


def _placeholder_note(placeholders: dict, width: int) -> list[str]:
    """The table's footnote on the values marked * (none without placeholders), wrapped to ``width``."""
    import textwrap

    if not placeholders:
        return []
    generic = dict.fromkeys(p for why in placeholders.values() for p in why.removeprefix("from ").split(", "))
    text = (
        f"* placeholder, not data: {', '.join(placeholders)} rest on {', '.join(generic)}, which neither the "
        "aircraft file nor --set gives; the predictions hold for these values, not for the aircraft. Give them "
        "in the aircraft file or with --set NAME=VALUE."
    )
    return textwrap.wrap(text, max(width, 60), subsequent_indent="  ")


def _string_map(f: Fields, key: str) -> dict[str, str]:
    """``key`` of a saved plan as a {str: str} mapping ({} when a plan written before it lacks it)."""
    if key not in f:
        return {}
    sub = f.sub(key)
    return {name: sub.string(name) for name in sub.doc}


def _saved_input(f: Fields, name: str) -> DesignInput:
    """The input history from the CSV file ``input`` names, renamed as saved."""
    path = f.string("input", allow_none=True)
    if path is None:
        raise f.error("input", "is null: the plan was written without its input CSV; pass input=")
    try:
        inp = read_input(path)
    except (FdmlError, OSError) as exc:
        raise f.error("input", f"names an input file that cannot be read: {exc}") from None
    return replace(inp, name=name)


def design(
    model,
    *,
    criterion: str = "d-optimal",
    duration: float = 20.0,
    amplitude: float = math.radians(1.0),
    band=None,
    dt: float = 0.02,
    rate: float = math.inf,
    noise=0.05,
    targets=(),
    steady: str = "derivatives",
    baselines=BASELINES,
    level: float = 0.05,
    given: DesignInput | None = None,
    free=None,
    refine: int = 40,
    detect=(),
) -> Design:
    """Design (or assess a given) input for ``model`` and compare it with classic inputs.

    Parameters
    ----------
    model : Model
        The truth, at its parameter values (``unsteady`` for discrimination).
    criterion : {"d-optimal", "a-optimal", "discriminate"}, optional
        What the input is optimised for (:mod:`fdml.design.optimize`).
    duration, amplitude : float, optional
        Record length (s) and peak elevator (rad).
    band : str or tuple, optional
        ``LO:HI[:STEP]`` rad/s: the input's band and the fit's (step default 0.1).
    dt, rate : float, optional
        Sample interval (s) and elevator rate limit (rad/s).
    noise : float or mapping, optional
        Fraction of output RMS in the 3-2-1-1 response, or stds.
    targets : sequence of str, optional
        The a-optimal subset.
    steady : {"derivatives", "steady"}, optional
        The steady model the unsteady one is told from: the six derivatives
        (default, the model Wells and Keskar fitted, as in ``fdml compare``) or
        the quasi-steady Wells-Keskar model.
    baselines : sequence of str, optional
        Classic inputs compared (:data:`fdml.design.inputs.CLASSIC_KINDS`).
    level : float, optional
        Test level of the detection probability.
    given : DesignInput, optional
        Predict for this input instead of designing one.
    free : sequence of str, optional
        Parameters to free as well (``b1`` of a gust model).
    refine : int, optional
        Full evaluations of the criterion that refine the optimised spectrum (0: none).
    detect : sequence of str, optional
        Library effects (``time_delay:alpha``, ``actuator_lag``, ``sensor_offset@az``) whose
        minimum detectable values (power 0.9 at ``level``) with the input are reported.

    Returns
    -------
    Design
        The input, its predicted bounds and those of the baselines.
    """
    if criterion not in CRITERIA:
        raise ParameterError(f"unknown criterion {criterion!r}; criteria: {', '.join(CRITERIA)}")
    if free:
        model = model.with_parameters(model.parameters.free(list(free)))
    if given is not None:
        dt, duration = float(given.t[1] - given.t[0]), float(given.t[-1])
    fband = parse_band((0.5, 10.0) if band is None else band, dt=dt)
    lim = Limits(amplitude=amplitude, duration=duration, dt=dt, rate=rate)
    ms = make_model(steady, model.aircraft, gust=model.gust) if model.kind == "unsteady" else None
    ref = classic_input("3211", lim, fband[:2]) if given is None else given
    stds = noise_stds(response(model, ref), noise)
    if given is None:
        score = _scorer(criterion, model, ms, stds, fband, targets)
        inp = optimal_input(
            criterion, model, lim, fband[:2], stds, targets=targets, steady=ms, score=score, refine=refine
        )
        base = {k: classic_input(k, lim, fband[:2]) for k in baselines}
    else:
        inp, base = given, {}
        criterion = "given"
    pred = predict(model, inp, noise=stds, band=fband)
    preds = {k: predict(model, b, noise=stds, band=fband) for k, b in base.items()}
    disc: dict[str, Discrimination] = {}
    if ms is not None:
        for k, b in {inp.name: inp, **base}.items():
            disc[k] = discriminate(model, ms, b, noise=stds, level=level, band=fband)
    found = tuple(e for eff in detect for e in minimum_detectable(model, eff, inp, noise=stds, level=level, band=fband))
    return Design(criterion, inp, pred, preds, disc, stds, fband, found, model.placeholders())


def _scorer(criterion: str, model, steady, stds, band, targets):
    """The criterion by the full prediction (larger is better)."""
    if criterion == "discriminate":
        return lambda inp: discriminate(model, steady, inp, noise=stds, band=band).noncentrality
    if criterion == "a-optimal":
        return lambda inp: -sum(predict(model, inp, noise=stds, band=band).cov_of(targets))
    return lambda inp: -float(np.linalg.slogdet(predict(model, inp, noise=stds, band=band).model_cov())[1])


def plot_design(d: Design, fig=None):
    """Input history, its spectrum against the baselines', and the predicted stderr ratios, under a title.

    The title names the criterion, the input, its length, peak and band; each
    input's entry in the spectrum legend gives its lambda and P(compare) when
    the model is unsteady (the probability that ``fdml compare`` favours the
    unsteady model, :mod:`fdml.design.discrimination`).  Legends sit beside
    the panels, off the data.

    Parameters
    ----------
    d : Design
        The plan.
    fig : matplotlib.figure.Figure, optional
        Figure to draw in (default: a new 11 x 8 in figure, constrained layout).

    Returns
    -------
    matplotlib.figure.Figure
        The figure, three axes.
    """
    import matplotlib.pyplot as plt

    from .inputs import spectrum

    fig = fig or plt.figure(figsize=(11, 8), layout="constrained")
    ax1, ax2, ax3 = fig.add_subplot(311), fig.add_subplot(312), fig.add_subplot(313)
    ax1.plot(d.input.t, np.degrees(d.input.de), label=d.input.name)
    ax1.set_xlabel("t, s")
    ax1.set_ylabel("de, deg")
    omega = np.linspace(d.band[0], d.band[1], 400)
    for name, inp in [(d.input.name, d.input)] + [(k, p.input) for k, p in d.baselines.items()]:
        if inp is None:  # a baseline read back without its history (Design.from_dict)
            continue
        ax2.semilogy(omega, np.degrees(spectrum(inp, omega)), label=_with_discrimination(name, d.discrimination))
    ax2.set_xlabel("omega, rad/s")
    ax2.set_ylabel("|de(j omega)|, deg s")
    ax2.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    gains = d.gains()
    names = list(d.predicted.to_dict())
    x = np.arange(len(names))
    for i, (b, g) in enumerate(gains.items()):
        ax3.bar(x + 0.8 * i / max(len(gains), 1), [g[n] for n in names], width=0.8 / max(len(gains), 1), label=b)
    ax3.axhline(1.0, color="k", lw=0.8)
    ax3.set_xticks(x + 0.4 - 0.4 / max(len(gains), 1), names, fontsize=8)
    ax3.set_ylabel("stderr ratio baseline / design")
    if gains:
        ax3.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.suptitle(_design_title(d))
    return fig


def _with_discrimination(name: str, disc: dict) -> str:
    """An input's legend entry: its name, and its lambda and P(compare) when it has them."""
    if name not in disc:
        return name
    return f"{name}: lambda {disc[name].noncentrality:.3g}, P(compare) {disc[name].vuong:.2f}"


def _design_title(d: Design) -> str:
    """What was designed: criterion, input, length, peak, band (and why no lambda, for a steady model)."""
    peak = math.degrees(float(np.max(np.abs(d.input.de)))) if len(d.input.de) else math.nan
    lo, hi = d.band[0], d.band[1]
    title = f"{d.criterion} design: {d.input.name}, {d.input.t[-1]:g} s, peak {peak:.3g} deg, band {lo:g}-{hi:g} rad/s"
    if not d.discrimination:
        title += "\n(steady model: no steady-vs-unsteady lambda or P(compare))"
    return title
