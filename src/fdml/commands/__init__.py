"""One module per ``fdml`` command; each has ``register(subparsers)`` and ``run(args)``."""
