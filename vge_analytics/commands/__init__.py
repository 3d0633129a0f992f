"""`vge` subcommands: one module per command, each exposing `register(app)`."""
