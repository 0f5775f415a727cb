"""report package of sins."""
