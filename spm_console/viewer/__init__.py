"""The 3D wrist view: meshcat served on 127.0.0.1 by a child process (or no view)."""
