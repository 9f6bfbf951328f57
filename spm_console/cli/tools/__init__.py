"""Commands that serve the lab beside driving the wrist: the latency check of the host, the
paper's reproduction report, the wrist exported for ROS and MuJoCo."""
