"""``fdml compare RECORD... --aircraft A``: steady and unsteady fits of the same records, and the evidence."""

from __future__ import annotations

import argparse

from ..errors import FdmlError, ParameterError
from ..outputs import atomic_savefig, atomic_write_text, check_output_folder
from . import _options as O
from ._common import assignments, check_band_option, fit_spectra, model_for_records

#: Files written into the -o folder.
FILES = {"comparison": "comparison.json", "summary": "summary.txt", "figure": "compare.png"}


def register(sub) -> None:
    p = sub.add_parser(
        "compare",
        help="fit steady and unsteady models to the same records: derivative shifts, which model the data favour",
        description="Fit the unsteady Wells-Keskar model and a steady model to the same records, print the six "
        "derivatives side by side (WK Tables 1 and 3), each model's ln det R and residual RMS, and the evidence "
        "(Vuong's non-nested test on the per-frequency log-likelihoods).",
    )
    p.add_argument("records", nargs="+", metavar="RECORD", help="record file(s), fitted jointly (as fdml fit)")
    O.add_model_options(p, kinds=False)
    O.add_steady_option(p)
    O.add_record_options(p)
    O.add_band_option(p)
    O.add_fit_options(p)
    O.add_output_option(
        p, kind="folder", metavar="DIR", help="comparison.json (both fits, shifts, evidence), summary.txt, compare.png"
    )
    O.add_json_option(p)


def _fit_both(args, records, data, kwargs):
    """(steady, unsteady) FitResults, each with the command's provenance; --fix/--free go to the model that has them."""
    from ..conditions import attach_conditions
    from ..estimate import fit

    fixed, free = assignments(args.fix), list(args.free or [])
    out, known = {}, set()
    for kind in ("unsteady", args.steady):
        ns = argparse.Namespace(**{**vars(args), "model": kind, "airspeed": None})
        model, prov = model_for_records(ns, records)
        names = set(model.parameters.names)
        known |= names
        res = fit(
            data,
            model,
            fix={k: v for k, v in fixed.items() if k in names},
            free=[n for n in free if n in names],
            **kwargs,
        )
        out[kind] = attach_conditions(res, model, records, prov)
    unknown = sorted((set(fixed) | set(free)) - known)
    if unknown:
        raise ParameterError(f"--fix/--free: {', '.join(unknown)} is a parameter of neither model")
    return out[args.steady], out["unsteady"]


def run(args) -> int:
    from ..cli import show
    from ..compare import Comparison, check_records_for_compare
    from ..io import check_same_rate, load_record
    from ..io.cli import record_options

    if args.aircraft is None:
        raise FdmlError("fdml compare needs --aircraft NAME or FILE.json (the unsteady model needs the geometry)")
    if args.output:
        files = {name: f"compare {key} file" for key, name in FILES.items()}
        check_output_folder(args.output, files, [*args.records, args.aircraft], what="compare folder")
    check_band_option(args.band)
    kwargs = O.fit_kwargs(args)
    opts = record_options(args)
    records = [load_record(path, **opts) for path in args.records]
    check_records_for_compare(records, gust=bool(args.gust))  # one aircraft first: its records' rates may differ too
    check_same_rate(records, args.records)
    steady, unsteady = _fit_both(args, records, fit_spectra(records, args.band, kwargs), kwargs)
    cmp = Comparison(steady=steady, unsteady=unsteady)
    files = _write(cmp, args.output) if args.output else {}
    show(
        args,
        {**cmp.brief(), **({"files": files} if files else {})},
        "\n".join([cmp.summary(), *(f"wrote {k:10s} {v}" for k, v in files.items())]),
    )
    return 0 if steady.converged and unsteady.converged else 1


def _write(cmp, folder) -> dict:
    """Write the comparison, its summary and its figure into ``folder`` (atomic writes); returns the paths."""
    from pathlib import Path

    from ..jsoncodec import write_json

    paths = {k: str(Path(folder) / v) for k, v in FILES.items()}  # the atomic writes make the folder
    write_json(paths["comparison"], cmp.to_dict(), what="compare comparison file")
    atomic_write_text(paths["summary"], cmp.summary() + "\n")
    atomic_savefig(cmp.plot, paths["figure"], dpi=110)
    return paths
