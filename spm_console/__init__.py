"""spm_console: operator software for 3-DOF spherical parallel manipulators.

Units: degrees at every interface, radians inside the core, mm for lengths,
seconds for time.
"""

__version__ = "0.1.0"
