"""GNSS/INS fusion: a closed-loop error-state Kalman filter around the strapdown kernel, an RTS smoother."""
