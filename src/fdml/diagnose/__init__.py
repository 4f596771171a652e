"""Sim-to-real gap diagnosis: where the model misses, which effect causes it, how far it shrinks."""
from .effects import (AugmentedModel, Effect, FreeParameterEffect, MatrixEffect, OutputEffect, Param,
                      default_library, get_effect, register_effect, registered_effects, unregister_effect)
