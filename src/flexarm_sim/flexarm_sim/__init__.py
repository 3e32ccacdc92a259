"""The simulated arm: plant (deflection), joint dynamics, the error sources of a real arm, the
true camera and its renderer, the simulated controller node and the fake controller."""

# What other packages may import (tests/test_layering.py holds every import to it).
PUBLIC = (
    'flexarm_sim.camera',
    'flexarm_sim.plant',
)
