"""The control core, by job: ``learning`` (sampling, predictors and model selection, datasets
and model files, training, model health, drift and refresh) and ``execution`` (compensation,
planning and bounds, the motion policies), both pure, and ``ros``, the nodes, their arm
interface and the scriptable client."""

# What other packages may import (tests/test_layering.py holds every import to it).
PUBLIC = (
    'flexarm_control.execution.modes',
    'flexarm_control.execution.tool_calibration',
    'flexarm_control.learning.at_payload',
    'flexarm_control.learning.dataset',
    'flexarm_control.learning.deflection_field',
    'flexarm_control.learning.model_store',
    'flexarm_control.learning.models',
    'flexarm_control.learning.payload_bounds',
    'flexarm_control.learning.sampling',
    'flexarm_control.learning.selection',
    'flexarm_control.ros.arm_claim',
    'flexarm_control.ros.client',
)
