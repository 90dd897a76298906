"""Camera-system design: coverage of targets by candidate cameras, the choice of cameras, and
the plan's verification by rendering. The highest stage below the pipeline and the CLI."""
