"""IMU noise characterization: overlapping Allan deviation, noise-term fit, sensor description (sins allan)."""
