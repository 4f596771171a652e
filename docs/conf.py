"""Sphinx configuration of the fdml documentation (``python -m sphinx -W -b html docs docs/_build/html``)."""

from __future__ import annotations

import os

os.environ.setdefault("MPLBACKEND", "Agg")

import fdml  # noqa: E402

project = "fdml"
author = "the fdml developers"
copyright = "the fdml developers, BSD-3-Clause"
version = release = fdml.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinx.ext.intersphinx",
    "numpydoc",
    "myst_parser",
    "sphinx_gallery.gen_gallery",
    "sphinxarg.ext",  # the CLI reference from fdml.cli.build_parser
]

# no en dashes for "--": option names in the CLI reference and the prose stay as typed
smartquotes_action = "qe"

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
exclude_patterns = ["_build", "_templates", "**.ipynb_checkpoints", "gallery/*.ipynb", "gallery/*.py"]
myst_enable_extensions = ["dollarmath", "amsmath", "deflist"]
myst_heading_anchors = 3

# API reference: autosummary writes one page per public object (docs/api/generated)
autosummary_generate = True
autosummary_imported_members = False
autosummary_ignore_module_all = False  # a module's page lists exactly its __all__
# names documented at the top level (fdml.X) are listed, not documented again, on their module's page
autosummary_context = {"toplevel": [n for n in fdml.__all__ if n != "__version__"]}
autodoc_default_options = {"members": False}
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False

intersphinx_mapping = {
    "python": ("https://docs.python.org/3", None),
}
# no network in the docs build: intersphinx only when asked for
if not os.environ.get("FDML_DOCS_INTERSPHINX"):
    intersphinx_mapping = {}

templates_path = ["_templates"]

sphinx_gallery_conf = {
    "examples_dirs": ["../examples"],
    "gallery_dirs": ["gallery"],
    "filename_pattern": r"/plot_",  # every examples/plot_*.py is executed
    "ignore_pattern": r"__init__\.py",
    "download_all_examples": False,
    "remove_config_comments": True,
    "within_subsection_order": "FileNameSortKey",
    "image_scrapers": ("matplotlib",),
    "show_memory": False,
    "abort_on_example_error": False,
    "only_warn_on_example_error": False,
}

html_theme = "pydata_sphinx_theme"
html_title = f"fdml {release}"
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "secondary_sidebar_items": ["page-toc"],
}
html_static_path: list[str] = []
