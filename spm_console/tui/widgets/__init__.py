"""Widgets of the operator console, one role per module."""
