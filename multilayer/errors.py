"""The two failure classes of the command line (docs/cli.md, exit codes)."""


class InputError(Exception):
    """Invalid input: the message names the file, the key path (and YAML line) and what
    is accepted. The CLI prints it and exits with code 2."""


class RunError(Exception):
    """A failure during a run (solver breakdown, output not writable). Exit code 1."""
