"""The compensator and the learner: ``execution`` (compensation, planning, goal bounds and the
check after a move, collection campaigns, tool calibration), pure, and ``ros``, the two nodes and
the scriptable client. The deflection model is flexarm_deflection's, the arm's motion
flexarm_motion's."""

# What other packages may import (tests/test_layering.py holds every import to it).
PUBLIC = (
    'flexarm_control.execution.modes',
    'flexarm_control.execution.tool_calibration',
    'flexarm_control.ros.client',
)
