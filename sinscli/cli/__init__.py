"""Command-line wiring: each command lives in its own module (listed in ``base.COMMANDS``),
registers itself on ``main`` and is imported when first used."""
from .base import main  # noqa: F401
