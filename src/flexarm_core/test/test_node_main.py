"""How a node ends on SIGINT and SIGTERM (:func:`flexarm_core.node_main.run`): the signal only
asks for the shutdown; the callback it lands in completes, the context stays up until the
executor has stopped, work threads end before the node is destroyed, and the exit code is 0.

rclpy's own handling raised KeyboardInterrupt inside the running callback and shut the
context down from its signal thread while the executor and the work threads still used the
node: the segmentation faults in ``destroy_node`` seen now and then at a graph's stop.
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
TIMEOUT = 60.0   # [s] a bound for a hung node; it ends within about a second


@pytest.mark.node
@pytest.mark.parametrize('sig', ['SIGINT', 'SIGTERM'])
def test_a_signal_mid_callback_ends_the_node_in_order(sig: str, domain_id: int,
                                                      tmp_path: Path) -> None:
    report = tmp_path / 'report.txt'
    env = {k: v for k, v in os.environ.items() if k != '_ROS_WHEELS_BOOTSTRAP_COMPLETE'}
    done = subprocess.run([sys.executable, str(HERE / 'signalled_node.py'), sig, str(report)],
                          env=env, capture_output=True, text=True, timeout=TIMEOUT)
    seen = report.read_text(encoding='utf-8').splitlines() if report.exists() else []
    assert done.returncode == 0, (done.returncode, seen, done.stderr[-2000:])
    assert seen == ['callback entered', 'callback completed', 'job ended before destroy',
                    'destroyed'], (seen, done.stderr[-2000:])
