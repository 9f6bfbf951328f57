"""The host: real-time scheduling, CPU placement, signals, child processes."""
