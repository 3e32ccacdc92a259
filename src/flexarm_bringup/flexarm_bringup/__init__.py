"""What starts and runs the flexarm graph, by job: ``orchestration`` (launcher, supervisor,
domains, transports, graph status), ``results`` (trials, figures, the words of an outcome),
``recording`` (the recorder node, bags and their tools), ``viz`` (scene and Foxglove nodes),
``site`` (calibrations through a running graph), ``experiments`` (demo, benchmark, study), and
``cli``, the ``flexarm`` command over them all. Each imports only the ones before it in that
order (tests/test_layering.py)."""

# What other packages may import (tests/test_layering.py holds every import to it).
PUBLIC = (
    'flexarm_bringup.cli',
    'flexarm_bringup.orchestration.launcher',
    'flexarm_bringup.orchestration.supervisor',
)
