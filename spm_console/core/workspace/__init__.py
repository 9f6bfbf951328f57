"""The workspace grid: its data at the leaf, exact checks, refinement, the build on top."""
