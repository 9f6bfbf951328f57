"""Regions for planning: P, the region cover and its graph, regions grown or refined around a segment."""
