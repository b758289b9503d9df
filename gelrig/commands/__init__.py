"""One module per ``gelrig`` subcommand; each has ``register(subparsers)``."""
