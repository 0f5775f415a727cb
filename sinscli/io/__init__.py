"""io package of sins."""
