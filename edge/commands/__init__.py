"""Subcommands of the ``edge`` CLI: one module per command, each with ``register(subparsers)``.

A module sets ``parser.set_defaults(func=...)``; ``func(args) -> int`` returns the exit code.
Bad user input raises ValueError (printed as one line, exit 2).
"""
