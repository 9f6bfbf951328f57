"""Live following: the receding-horizon QP re-planned every period, its targets and their projection into the region."""
