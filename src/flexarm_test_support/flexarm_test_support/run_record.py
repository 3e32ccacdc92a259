"""The run record `flexarm up` writes (its supervisor, domain, node processes), written by a test
that starts nodes itself: ``flexarm status`` then knows the arm's nodes at once instead of
waiting out a fresh participant's discovery."""
from __future__ import annotations

import json
import os
from pathlib import Path

from flexarm_core.graph_locks import RECORD
from flexarm_core.paths import RUNS_DIR


def record_supervisor(domain_id: int, namespace: str, nodes: list) -> Path:
    """The run record `flexarm up` writes for the arm (this process as its supervisor), so
    that `flexarm status` knows the arm's nodes at once instead of waiting out discovery."""
    run = RUNS_DIR / f'{namespace}-{domain_id}'
    run.mkdir(parents=True, exist_ok=True)
    (run / RECORD).write_text(json.dumps({
        'supervisor_pid': os.getpid(), 'domain_id': domain_id, 'robot': 'sim',
        'namespace': namespace, 'remote': [],
        'nodes': {n.spec.name: {'pid': n.process.pid, 'restarts': 0, 'exit_code': None}
                  for n in nodes}}))
    return run / RECORD
