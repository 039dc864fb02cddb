"""The failure classes of the command line (docs/cli.md, exit codes)."""


class InputError(Exception):
    """Invalid input: the message names the file, the key path (and YAML line) and what
    is accepted. The CLI prints it and exits with code 2."""


class RunError(Exception):
    """A failure during a run (solver breakdown, output not writable). Exit code 1."""


class Interrupted(KeyboardInterrupt):
    """A run stopped cleanly by a signal; the CLI exits with ``128 + signum`` (130 for
    Ctrl-C, 143 for SIGTERM, 129 for SIGHUP)."""

    def __init__(self, message: str, signum: int = 2):
        super().__init__(message)
        self.exit_code = 128 + int(signum)


def reason(exc: BaseException) -> str:
    """What ``exc`` says went wrong, without the path an ``OSError`` quotes: the message it
    goes into names the file once (a path of thousands of characters was quoted twice)."""
    if isinstance(exc, OSError) and exc.strerror:
        return exc.strerror
    return str(exc)
