"""MCAP bags: the recorder node, the bag writer and its schemas, which topics a recording takes,
and the bag tools (``flexarm bag info``, ``flexarm bag export``)."""
