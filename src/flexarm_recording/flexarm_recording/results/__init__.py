"""What a run's goals came to: trial bookkeeping, the result figures and the words an outcome
is told in (shared by the experiments, the bag tools and the command line)."""
