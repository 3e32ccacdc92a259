"""``python -m flexarm_bringup.cli``: the ``flexarm`` command."""
from flexarm_bringup.cli import run

run()
