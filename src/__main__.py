"""Entry point for ``python -m simgap``."""

from simgap.cli import app

app()
