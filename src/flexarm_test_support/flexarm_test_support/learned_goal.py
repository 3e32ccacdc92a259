"""What the node tests of a working graph end with: collect in region B, train, and reach a
PREDICTIVE goal within 0.1 mm; each step asserted with its server's reason."""
from __future__ import annotations

from typing import Any

from flexarm_msgs.action import CollectSamples, MoveToPose


def learn_and_reach(client: Any, count: int, dataset: str, target: tuple[float, float, float],
                    collect_timeout: float) -> None:
    collected = client.collect(count, region='B', dataset=dataset, timeout=collect_timeout)
    assert collected.error_code == CollectSamples.Result.SUCCESSFUL, collected.error_string
    assert collected.skipped == 0
    trained = client.train('', dataset=dataset, timeout=120)
    assert trained.success, trained.message
    client.wait_for_model(trained.model_version, timeout=20)
    moved = client.move_to(*target, mode='predictive', timeout=120)
    assert moved.error_code == MoveToPose.Result.SUCCESSFUL, moved.error_string
    assert moved.position_error < 0.1e-3, moved.position_error
