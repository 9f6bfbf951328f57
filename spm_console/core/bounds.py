"""Documented bounds of what the console plans (plain constants, no imports: cheap to load).

Listed in docs/cli-reference.md, "Input bounds"; the CLI, scripts and the planners share them.
"""

from __future__ import annotations

#: Rated no-load speed of the Dynamixel MX-106 at its recommended 12 V supply: 45 rev/min
#: = 270 deg/s (ROBOTIS e-manual, MX-106 and MX-106(2.0) specifications; 41 rev/min at
#: 11.1 V, 55 rev/min at 14.8 V). No planned speed bound may exceed it.
MX106_NO_LOAD_SPEED_DEGPS = 270.0

#: Largest horizon N of a planning problem (100 s at Ts = 20 ms): ``plan mvn --steps`` and
#: the minimum-time search.
N_MAX = 5000

#: Largest number of constrained instants N·K (samples and intersample points): bounds the
#: QP's size (rows ≈ 70·N·K with a 61-face region) and so its memory and time.
MAX_INSTANTS = 100_000
