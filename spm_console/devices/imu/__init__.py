"""Inertial measurement units: the Bosch BNO055 in UART mode (pure codec, pyserial driver)."""
