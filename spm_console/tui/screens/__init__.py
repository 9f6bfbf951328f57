"""The console's screens, one per step of the flow."""
