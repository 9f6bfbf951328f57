"""Devices: Dynamixel protocol codec (pure), serial transport, servo bus, emulated bus; the BNO055
IMU (pure codec, serial driver) and its emulator."""
