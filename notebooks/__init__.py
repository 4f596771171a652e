"""Not a package of code: this file makes notebooks/conftest.py import as ``notebooks.conftest``.

pytest imports every conftest.py; two of them named plain ``conftest`` (tests/ and notebooks/)
would shadow each other, and ``from conftest import ...`` in the tests would find the wrong one.
"""
