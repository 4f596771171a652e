"""Every public function, class and method has a numpydoc docstring that passes numpydoc's validation.

The public API is ``fdml.__all__`` and the ``__all__`` of every public module (no leading
underscore in its dotted path; the command modules under ``fdml.commands`` are the CLI's own and
are covered by the CLI reference instead), plus the public methods and properties those classes
define. Each object is checked with :func:`numpydoc.validate.validate` for the codes in
:data:`CHECKS`, the way python-control checks its own docstrings. A method that overrides a
documented method of a base class inherits its docstring (as Sphinx shows it), so it passes GL08.

SS05 (a summary starting with an infinitive verb) and the ES01/SA01/EX01
sections are not required.
"""

from __future__ import annotations

import enum
import importlib
import inspect
import pkgutil

import numpydoc.validate as numpydoc_validate  # the test extra (and the docs extra) install numpydoc
import pytest

import fdml

#: numpydoc validation codes every public docstring must pass
#: (https://numpydoc.readthedocs.io/en/latest/validation.html).
CHECKS = {
    "GL01",  # the summary starts right after, or on the line after, the opening quotes
    "GL02",  # closing quotes on the line after the last text
    "GL03",  # no double blank lines
    "GL05",  # no tabs
    "GL06",  # no unknown section
    "GL07",  # sections in numpydoc's order
    "GL08",  # a docstring at all
    "GL10",  # reST directives followed by two colons
    "PR01",  # every parameter documented
    "PR04",  # every parameter has a type
    "PR07",  # every parameter has a description
    "PR08",  # a parameter description starts with a capital letter
    "RT01",  # a Returns section (for a function that returns something)
    "RT03",  # the returned value has a description
    "RT04",  # a return description starts with a capital letter
    "SS01",  # a summary
    "SS02",  # the summary starts with a capital letter
    "SS03",  # the summary ends with a period
    "SS04",  # no leading whitespace in the summary
    "SS06",  # the summary fits on one line
    "PR02",  # no documented parameter that does not exist
    "PR03",  # parameters documented in signature order
    "PR05",  # a parameter type does not end with a period
    "PR06",  # types spelled int, bool, str
    "PR10",  # a space before the colon of "name : type"
    "RT02",  # a Returns entry gives only the type, unless several values are returned
    "YD01",  # a generator (or context manager) has a Yields section
}

#: Subpackages that are not public API.
PRIVATE_PACKAGES = ("fdml.commands",)


def _public_modules() -> list[str]:
    names = ["fdml"]
    for info in pkgutil.walk_packages(fdml.__path__, "fdml."):
        parts = info.name.split(".")
        if any(p.startswith("_") for p in parts[1:]) or info.name.startswith(PRIVATE_PACKAGES):
            continue
        names.append(info.name)
    return [n for n in names if hasattr(importlib.import_module(n), "__all__")]


def _qualname(obj) -> str:
    return f"{obj.__module__}.{obj.__qualname__}"


def _public_objects() -> dict[str, object]:
    """Import path -> object for every public function, class, method and property."""
    found: dict[int, tuple[str, object]] = {}
    for modname in _public_modules():
        mod = importlib.import_module(modname)
        for name in mod.__all__:
            obj = getattr(mod, name)
            if (inspect.isclass(obj) or inspect.isfunction(obj)) and obj.__module__.startswith("fdml"):
                found.setdefault(id(obj), (_qualname(obj), obj))
    out = {}
    for path, obj in found.values():
        out[path] = obj
        if inspect.isclass(obj):
            for name, member in vars(obj).items():
                if name.startswith("_"):
                    continue
                if isinstance(member, (staticmethod, classmethod)):
                    member = member.__func__
                if inspect.isfunction(member) or isinstance(member, property):
                    out[f"{path}.{name}"] = (obj, name, member)
    return out


def _inherited_doc(cls, name: str) -> bool:
    """Whether a base class documents the method ``name`` that ``cls`` overrides without a docstring."""
    for base in cls.__mro__[1:]:
        member = vars(base).get(name)
        if member is not None and getattr(member, "__doc__", None):
            return True
    return False


OBJECTS = _public_objects()


def _errors(path: str) -> list[tuple[str, str]]:
    target = OBJECTS[path]
    # validate the object itself where the tests replace the module attribute (conftest wraps
    # fdml.io.paths.data_dir so that tests skip without FDML_DATA)
    loaded = numpydoc_validate.Validator._load_obj(path)
    replaced = not isinstance(target, tuple) and loaded is not target
    result = numpydoc_validate.validate(numpydoc_validate.get_doc_object(target) if replaced else path)
    errors = [(code, msg) for code, msg in result["errors"] if code in CHECKS]
    if inspect.isclass(target) and issubclass(target, enum.Enum):
        # an enumeration is made by value lookup, not by its constructor, whose signature (the
        # functional API's names, module, qualname, ...) changes between Python versions
        errors = [e for e in errors if e[0] not in ("PR01", "PR02")]
    if isinstance(target, tuple):  # a method or property: (class, name, member)
        cls, name, member = target
        if not getattr(member, "__doc__", None) and _inherited_doc(cls, name):
            errors = [e for e in errors if e[0] != "GL08"]
    return errors


def test_the_public_api_is_found():
    # a sanity check on the walk: the everyday names and a method of each main class are in it
    for path in ("fdml.estimate.fit", "fdml.results.FitResult", "fdml.record.Record", "fdml.models.base.Model"):
        assert path in OBJECTS, path
    assert any(p.startswith("fdml.results.FitResult.") for p in OBJECTS)


@pytest.mark.parametrize("path", sorted(OBJECTS))
def test_numpydoc_docstring(path):
    errors = _errors(path)
    assert not errors, f"{path}: " + "; ".join(f"{code} {msg}" for code, msg in errors)
