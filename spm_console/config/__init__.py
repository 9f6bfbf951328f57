"""The profile: its schema, its checks, loading it, and the one adapter to the core's models."""
