"""Emulated devices: the MX-106 bus on a socket or a pseudo-terminal, in-process or as a child;
a BNO055 IMU on a pseudo-terminal."""
