"""Live following in the servo loop: targets, region hopping, the loop."""
