"""One registry of channels, units and record formats (issue 10): fdml.channels, and nowhere else.

The scan reads every module of src/fdml as a syntax tree: a tuple, list or set literal that
spells the output channels (or the required ones, or the record formats), or a dict literal
mapping channels to their units, anywhere but fdml/channels.py is a second copy of the registry.
The readers' records are then checked against the registry, and the registry's SI units against
the conversion table of fdml.io.units (an independent table: the SI unit is its factor-1 unit).
"""

import ast
import math
from pathlib import Path

import numpy as np
import pytest

import fdml
from fdml import channels
from fdml.constants import DEG
from fdml.io import FORMATS, data_path, load_record
from fdml.io.units import QUANTITY, UNITS, normalise_unit

SRC = Path(fdml.__file__).parent
REGISTRY = SRC / "channels.py"

OUTPUTS = {"alpha", "q", "az"}
REQUIRED = {"de", "alpha", "q", "az"}
INPUTS = {"de", "alpha_w"}
#: Two record-format names no other literal collection would hold together.
FORMAT_MARK = {"sidpac", "dlr-asc"}


def _strings(node):
    """The string constants of a literal collection, or None if it holds anything else."""
    out = []
    for e in node.elts:
        if not (isinstance(e, ast.Constant) and isinstance(e.value, str)):
            return None
        out.append(e.value)
    return out


def _copies(path: Path) -> list[str]:
    """Literal copies of the registry in one module: ``line: what``."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, (ast.Tuple, ast.List, ast.Set)):
            items = _strings(node)
            if items is None:
                continue
            if set(items) in (OUTPUTS, REQUIRED, INPUTS):
                found.append(f"{node.lineno}: channel collection {items}")
            elif FORMAT_MARK <= set(items):
                found.append(f"{node.lineno}: record formats {items}")
        elif isinstance(node, ast.Dict):
            keys = {k.value for k in node.keys if isinstance(k, ast.Constant)}
            values = [v for v in node.values if isinstance(v, ast.Constant) and isinstance(v.value, str)]
            if OUTPUTS <= keys and len(values) == len(node.values) and any(v.value == "rad/s" for v in values):
                found.append(f"{node.lineno}: unit map {sorted(keys)}")
    return found


def test_no_module_but_channels_defines_channels_units_or_formats():
    copies = {str(p.relative_to(SRC)): c for p in sorted(SRC.rglob("*.py")) if p != REGISTRY and (c := _copies(p))}
    assert copies == {}


def test_the_scan_finds_the_registry_itself():
    # the scan is not vacuous: it sees the outputs, the required channels, the units and the formats
    kinds = " ".join(_copies(REGISTRY))
    for what in ("channel collection", "unit map", "record formats"):
        assert what in kinds
    assert "['de', 'alpha_w']" in kinds


def test_registry_is_what_the_package_uses():
    from fdml.io.cli import add_record_arguments
    from fdml.models.base import OUTPUTS as model_outputs
    from fdml.record import REQUIRED_SIGNALS, SIGNALS

    assert model_outputs is channels.OUTPUTS
    assert fdml.make_model("steady", "navion").outputs == channels.OUTPUTS
    assert SIGNALS is channels.SIGNALS and REQUIRED_SIGNALS is channels.REQUIRED
    assert FORMATS is channels.FORMATS
    import argparse

    p = argparse.ArgumentParser()
    add_record_arguments(p)
    fmt = next(a for a in p._actions if a.dest == "format")
    assert tuple(fmt.choices) == channels.FORMATS


def test_si_units_are_the_factor_one_units_of_the_conversion_table():
    for sig, unit in channels.SIGNALS.items():
        assert UNITS[QUANTITY[sig]][normalise_unit(unit)] == 1.0, sig


def test_display_units_are_degrees():
    # one degree is pi/180 rad (constants.DEG, exact): a value of DEG rad reads as 1 deg
    for unit, shown in (("rad", "deg"), ("rad/s", "deg/s"), ("rad/s^2", "deg/s^2")):
        f, u = channels.display_unit(unit)
        assert u == shown and f * DEG == pytest.approx(1.0, rel=1e-15)
    assert channels.display_unit("g") == (1.0, "g")


@pytest.mark.parametrize(
    "rel, fmt",
    [
        ("twin_otter/totter_lon_020213f1_017.mat", "sidpac"),
        ("hfb320/hfb320_1_10.asc", "dlr-asc"),
        ("attas/fAttasElv1.mat", "dlr-mat"),
    ],
)
def test_readers_produce_registry_channels_and_units(rel, fmt):
    rec = load_record(data_path(rel), t0=2.0, t1=4.0)
    assert rec.meta["format"] == fmt and fmt in channels.FORMATS
    assert set(channels.REQUIRED) <= set(rec.signals) <= set(channels.SIGNALS)
    for k, unit in rec.meta["units"].items():
        if k in channels.CONDITION_UNITS:
            assert unit == channels.CONDITION_UNITS[k], k
    assert {"U", "rho"} <= set(rec.meta["units"])
    # the outputs arrive in the registry's units: the specific force of near-level flight is about
    # -1 g (body z positive down), alpha a few degrees in rad (|alpha| < 0.5 rad), not degrees
    assert np.mean(rec["az"]) == pytest.approx(-1.0, abs=0.3)
    assert math.isfinite(rec.meta["U"]) and np.all(np.abs(rec["alpha"]) < 0.5)
