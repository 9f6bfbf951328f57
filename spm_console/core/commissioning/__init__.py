"""Commissioning a wrist as built: horn offsets, the IMU's mount, the base's tilt and each leg's
arcs from the gravity an IMU on the platform measures at rest (gravity: the model and its exact
Jacobian through (4), (11), (12); fit; observability: what the data determine; design: which
poses to measure; verify: held-out poses)."""
