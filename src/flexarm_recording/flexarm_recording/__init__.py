"""Recording trials and reading them back: the recorder node, the bag writer and its schemas,
which topics a recording takes, the bag tools (``flexarm bag info``, ``flexarm bag export``),
and in ``results`` what a run's goals came to (trials, figures, the words of an outcome)."""

# What other packages may import (tests/test_layering.py holds every import to it).
PUBLIC = (
    'flexarm_recording.bag_schema',
    'flexarm_recording.bag_tools',
    'flexarm_recording.results.accuracy_report',
    'flexarm_recording.results.outcome_text',
    'flexarm_recording.results.plots',
    'flexarm_recording.results.trials',
    'flexarm_recording.topic_discovery',
)
