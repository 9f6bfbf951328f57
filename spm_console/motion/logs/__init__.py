"""Run logs: writing, reading, listing, the process identity of a run."""
