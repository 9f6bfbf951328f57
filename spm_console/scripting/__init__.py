"""Scripted (headless) sessions: the TOML file's typed steps (``steps``) and the runner
(``runner``) that drives the operator runtime through them."""
