"""The process that owns the port: protocol, server, executor, safety, homing, runs."""
