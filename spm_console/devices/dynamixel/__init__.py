"""Dynamixel Protocol 1.0/2.0 codecs, the control table, the serial bus."""
