"""Subcommands of the ``knitframe`` CLI, one module each."""
