"""``python -m flexarm_cli``: the ``flexarm`` command."""
from flexarm_cli import run

run()
