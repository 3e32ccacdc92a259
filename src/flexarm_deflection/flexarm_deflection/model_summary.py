"""What the health reports read of an announced model: ``flexarm_msgs/ModelInfo`` has these
fields, so the nodes pass the message itself, and the pure builders need no message package."""
from __future__ import annotations

from typing import Protocol


class ModelSummary(Protocol):
    version: str
    kind: str
    dataset: str
    warning: str     # '' when the model fits the arm and payload it drives
