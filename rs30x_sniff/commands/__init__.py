"""Subcommands of the CLI: one module each, thin: parse, call the library, print."""
