"""Names that do not mislead (issue 10): no function hides a module of its name, and the
modules are named for what they hold.

Each check runs in a fresh interpreter, because whether an attribute of a package is a
function or a submodule depends on what was imported before (importing ``pkg.name`` binds
the module as ``pkg.name``).
"""

import subprocess
import sys

import fdml


def _run(code: str) -> None:
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr


def test_spectra_stays_the_function_after_every_import():
    _run(
        "import importlib, pkgutil, types, fdml\n"
        "for m in pkgutil.walk_packages(fdml.__path__, 'fdml.'):\n"
        "    if not m.name.endswith('__main__'):\n"
        "        importlib.import_module(m.name)\n"
        "from fdml import spectra\n"
        "import fdml.spectral\n"
        "assert isinstance(spectra, types.FunctionType) and fdml.spectra is spectra, spectra\n"
        "assert fdml.spectral.spectra is spectra\n"
    )


def test_no_public_name_of_a_package_is_also_a_submodule():
    # after importing everything, pkg.leaf must be the module pkg.leaf, and no package may
    # export (``__all__``) a name that is also one of its submodules
    _run(
        "import importlib, pkgutil, sys, fdml\n"
        "mods = [m.name for m in pkgutil.walk_packages(fdml.__path__, 'fdml.') if not m.name.endswith('__main__')]\n"
        "for name in mods:\n"
        "    importlib.import_module(name)\n"
        "bad = []\n"
        "for name in mods:\n"
        "    pkg, _, leaf = name.rpartition('.')\n"
        "    parent = sys.modules[pkg]\n"
        "    if leaf in getattr(parent, '__all__', ()) or vars(parent).get(leaf) is not sys.modules[name]:\n"
        "        bad.append(name)\n"
        "assert bad == [], bad\n"
    )


def test_old_misleading_module_names_are_gone():
    _run(
        "import importlib.util\n"
        "for name in ('fdml.compat', 'fdml.spectra', 'fdml.diagnose.validate'):\n"
        "    assert importlib.util.find_spec(name) is None, name\n"
        "import fdml.flightpath as fp\n"
        "assert callable(fp.check_compatibility)\n"
    )


def test_load_record_is_exported_at_the_top_level():
    from fdml.io import load_record

    assert "load_record" in fdml.__all__
    assert fdml.load_record is load_record


def test_the_new_public_types_are_exported_at_the_top_level():
    from fdml.estimate import EstimatorSettings
    from fdml.parallel import execute
    from fdml.parameters import Role, Slot
    from fdml.warning_log import RecordedWarning

    for name, obj in [
        ("Role", Role),
        ("Slot", Slot),
        ("EstimatorSettings", EstimatorSettings),
        ("RecordedWarning", RecordedWarning),
        ("execute", execute),
    ]:
        assert name in fdml.__all__ and getattr(fdml, name) is obj, name
