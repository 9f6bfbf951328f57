"""What the runtime sends beyond the verified references: the load's offset and the settling
shift at the goal."""
