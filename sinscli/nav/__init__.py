"""nav package of sins."""
