"""Convex polytopes {θ : A θ ≤ b}: the region type, LPs, inscribed ellipsoids, IRIS."""
