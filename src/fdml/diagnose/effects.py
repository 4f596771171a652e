"""Moved to :mod:`fdml.models.effects` (issue 8); this name is an alias of that module."""

import sys

from ..models import effects as _moved

sys.modules[__name__] = _moved
