"""Subcommands of this area (filled in by its issue)."""

import argparse


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add this area's subcommands to the `pinarray` parser."""
