"""Devices: Dynamixel protocol codec (pure), serial transport, servo bus, emulated bus."""
