"""The notebooks under pytest (nbmake): those that read the real flight records skip without FDML_DATA.

nbmake runs a notebook in a kernel and reports only pass or fail; it has no skip of its own, and a
notebook that ends early by itself would be reported as passed.  So the skip is decided here,
before the kernel starts: a notebook whose code calls ``fdml.io.data_path`` (the one way fdml reads
the shared records) needs ``FDML_DATA``, and without it the notebook is skipped with a reason that
names the variable, as ``tests/conftest.py`` does for the tests.  With ``FDML_DATA`` set, the
notebook runs, and a missing file fails it naming the file.

A notebook whose kernel died before it ran a cell (ZMQ: the port it was given taken by a parallel
process) runs once more; seen once in a CI run, on 03_sundowner_table3, which passed on the next run.
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import pytest

from fdml.io.paths import DATA_ENV

#: A call of fdml.io.data_path in a code cell (an import of the name alone is not a call).
_READS_RECORDS = re.compile(r"\bdata_path\s*\(")


def reads_real_records(notebook: Path) -> bool:
    """True when a code cell of ``notebook`` calls ``data_path(...)``."""
    cells = json.loads(Path(notebook).read_text(encoding="utf-8")).get("cells", [])
    return any(_READS_RECORDS.search("".join(c.get("source", ""))) for c in cells if c.get("cell_type") == "code")


def pytest_runtest_setup(item):
    """Skip, naming FDML_DATA, a notebook that reads the real records when FDML_DATA is unset."""
    path = Path(str(getattr(item, "path", "")))
    if path.suffix == ".ipynb" and not os.environ.get(DATA_ENV) and reads_real_records(path):
        pytest.skip(f"needs the real flight records: set {DATA_ENV}=/path/to/shared/data")


#: What nbmake reports when a notebook's kernel died before it ran a cell: ZMQ found the port it was
#: given taken by a parallel process ("Address already in use"), an accident of the machine.
_KERNEL_NEVER_STARTED = "Kernel died before replying to kernel_info"


def kernel_never_started(reports) -> bool:
    """True when a notebook failed because its kernel never started (nothing of the notebook ran)."""
    return any(r.failed and _KERNEL_NEVER_STARTED in str(r.longrepr) for r in reports)


def pytest_runtest_protocol(item, nextitem):
    """A notebook whose kernel never started runs once more; any other failure stands as it is."""
    if Path(str(getattr(item, "path", ""))).suffix != ".ipynb":
        return None
    from _pytest.runner import runtestprotocol

    item.ihook.pytest_runtest_logstart(nodeid=item.nodeid, location=item.location)
    reports = runtestprotocol(item, nextitem=nextitem, log=False)
    if kernel_never_started(reports):
        reports = runtestprotocol(item, nextitem=nextitem, log=False)
    for report in reports:
        item.ihook.pytest_runtest_logreport(report=report)
    item.ihook.pytest_runtest_logfinish(nodeid=item.nodeid, location=item.location)
    return True
