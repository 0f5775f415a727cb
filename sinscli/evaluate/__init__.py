"""Evaluation: navigation errors against a truth (seed 000 tables), trajectory metrics (ATE/RPE), the fusion
filter's consistency, and what an IMU log holds (sins info). Numbers only; report/ draws them."""
