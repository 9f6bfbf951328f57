"""Commissioning a wrist as built, from a front end: the stages in order (:mod:`.stages`:
discover, jig, map, zero; :mod:`.imu_stage`: the poses and fit of the IMU stage), the leg map
from the IMU (:mod:`.leg_map`), the run log (:mod:`.log`), and one commissioning as the CLI and
the console run it (:mod:`.run`)."""
