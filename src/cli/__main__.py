"""``python -m simgap.cli``."""

from simgap.cli import app

app()
