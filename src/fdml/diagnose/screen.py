"""Score (Lagrange-multiplier) screen of candidate effects: moved to :mod:`fdml.score`.

The screen, its context and result are shared with every fit's adequacy check
(:mod:`fdml.adequacy`), which must not import the diagnosis package; they are
re-exported here for the diagnosis's modules and existing imports.
"""

from ..score import (
    ALIAS_LIMIT,
    ScreenContext,
    ScreenResult,
    power_noncentrality,
    screen,
)

__all__ = ["ALIAS_LIMIT", "ScreenContext", "ScreenResult", "power_noncentrality", "screen"]
