"""What the command line does with its streams: stdout kept for the JSON answer, a live progress
display on a terminal's stderr."""
