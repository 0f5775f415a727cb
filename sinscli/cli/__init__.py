"""Command-line wiring: each command lives in its own module and registers on ``main``."""
from .base import main  # noqa: F401

# One import per command module (each adds its command to ``main``).
from . import compare  # noqa: F401,E402
from . import navigate  # noqa: F401,E402
from . import simulate  # noqa: F401,E402
from . import info  # noqa: F401,E402
from . import convert  # noqa: F401,E402
from . import align  # noqa: F401,E402
