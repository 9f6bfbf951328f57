"""The servos' closed-loop model (eq. 27-28), its identification and the Kalman estimation."""
