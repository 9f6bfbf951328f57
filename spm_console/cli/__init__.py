"""Headless command-line interface (an API: data on stdout, diagnostics on stderr)."""
