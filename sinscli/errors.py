"""The one exception type a user ever sees: a one-line message, exit status 2."""


class SinsError(Exception):
    """Bad input or an impossible request.

    The message is a single line that names the file, row or field and what was
    expected. The CLI prints it as ``sins: error: <message>`` and exits with 2.
    """

    exit_code = 2

    def __init__(self, message: str):
        super().__init__(" ".join(str(message).split()))
