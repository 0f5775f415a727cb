"""align package of sins."""
