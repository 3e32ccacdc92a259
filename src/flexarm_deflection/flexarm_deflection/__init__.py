"""The deflection model the graph learns and compensates with, pure and without ROS: the
deflection pairs and where to take them, the predictors, training and model selection, model
files, error bounds, the model's health, drift correction and refresh. The learner node trains
on it, the compensator predicts with it, and the tools read its model files."""

# What other packages may import (tests/test_layering.py holds every import to it).
PUBLIC = (
    'flexarm_deflection.active_sampling',
    'flexarm_deflection.at_payload',
    'flexarm_deflection.cross_validation',
    'flexarm_deflection.dataset',
    'flexarm_deflection.deflection_field',
    'flexarm_deflection.deflection_slope',
    'flexarm_deflection.error_bound',
    'flexarm_deflection.learner_status',
    'flexarm_deflection.model_health',
    'flexarm_deflection.model_store',
    'flexarm_deflection.model_summary',
    'flexarm_deflection.models',
    'flexarm_deflection.payload_bounds',
    'flexarm_deflection.payload_record',
    'flexarm_deflection.predictors',
    'flexarm_deflection.predictors.base',
    'flexarm_deflection.predictors.kinematic',
    'flexarm_deflection.refresh',
    'flexarm_deflection.sampling',
    'flexarm_deflection.selection',
    'flexarm_deflection.training',
    'flexarm_deflection.training_job',
)
