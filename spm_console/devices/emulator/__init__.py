"""The emulated MX-106 bus on a socket or a pseudo-terminal, in-process or as a child."""
