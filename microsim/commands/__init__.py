"""One module per ``microsim`` command; each has ``register(subparsers)``."""
