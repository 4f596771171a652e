"""Moved to :mod:`fdml.models.effect_library` (issue 8); this name is an alias of that module."""

import sys

from ..models import effect_library as _moved

sys.modules[__name__] = _moved
