"""sim package of sins."""
