"""The failure classes of the command line (docs/cli.md, exit codes)."""

import math
import os
import sys
from typing import TextIO


class InputError(Exception):
    """Invalid input: the message names the file, the key path (and YAML line) and what
    is accepted. The CLI prints it and exits with code 2."""


class RunError(Exception):
    """A failure during a run (solver breakdown, output not writable). Exit code 1."""


class Interrupted(KeyboardInterrupt):
    """A run stopped cleanly by a signal; the CLI exits with ``128 + signum`` (130 for
    Ctrl-C, 143 for SIGTERM, 129 for SIGHUP) and prints the message unless ``said`` (the
    command printed it, with what it kept)."""

    def __init__(self, message: str, signum: int = 2, *, said: bool = False):
        super().__init__(message)
        self.exit_code = 128 + int(signum)
        self.said = said


class Stop(BaseException):
    """A stop the user requested (the first Ctrl-C, SIGTERM or SIGHUP of a run), raised
    where the run may stop with its state whole: between kernel calls, and in a rheology
    plugin's Python code (the step is abandoned: a plugin that never returns stopped the
    run only at a second signal).  No failure of the code it passes through."""


def reason(exc: BaseException) -> str:
    """What ``exc`` says went wrong, without the path an ``OSError`` quotes: the message it
    goes into names the file once (a path of thousands of characters was quoted twice)."""
    if isinstance(exc, OSError) and exc.strerror:
        return exc.strerror
    return str(exc)


def said(exc: BaseException) -> str:
    """``str(exc)`` on one line, its line feeds written ``\\n``, or a note that it cannot be
    shown: a third party's exception whose ``__str__`` raises (or returns no string)
    replaced the message naming the plugin that raised it by its own, and one holding a
    line feed printed the message over two lines, the second read as another message."""
    try:
        text = str(exc)
    except Exception as error:  # noqa: BLE001 - any failure of third-party code
        return f"(its message cannot be shown: str() raised {type(error).__name__})"
    return text.replace("\n", "\\n")


def described(exc: BaseException) -> str:
    """``exc``'s type and message (:func:`said`), as a failure of third-party code is named."""
    return f"{type(exc).__name__}: {said(exc)}"


REMOVED_WORKING_DIRECTORY = (
    "the working directory no longer exists (removed after this shell entered it), and relative paths "
    "(the default output directory results/<name> too) and numba compiling the kernels for their first "
    "use read it; accepted: a command started in a directory that exists"
)
"""Said where a relative path cannot be resolved, or numba cannot compile (it makes the
paths of the kernels' sources relative for its messages), because the working directory is
gone (:func:`working_directory_removed`): ``os.getcwd()``'s error names no file."""


def working_directory_removed() -> bool:
    """True if the working directory no longer exists (removed after the shell entered it)."""
    try:
        os.getcwd()
    except FileNotFoundError:
        return True
    return False


MAX_COUNT_DIGITS = 18
"""Digits of a count read from text (an option, an environment variable): past Python's
4300 a conversion raised ``ValueError`` where the text was checked as digits."""


def ascii_count(text: str) -> int | None:
    """The integer ``text`` writes in ASCII digits (spaces around them allowed, at most
    :data:`MAX_COUNT_DIGITS` of them after leading zeros), else None: ``int`` alone also
    reads ``1_000`` and the digits of other scripts (``'\u0663'``, an Arabic-Indic 3), and
    raised ``ValueError`` for a count of 5000 digits."""
    digits = text.strip()
    if not (digits.isascii() and digits.isdigit() and len(digits.lstrip("0")) <= MAX_COUNT_DIGITS):
        return None
    return int(digits)


SHOWN_CHARACTERS = 60
"""Characters of a value, a key or a name a message quotes from the input, at most."""


def shortened(text: str) -> str:
    """``text`` cut to :data:`SHOWN_CHARACTERS`, its end written ``...``: a message quotes
    what it got, not a whole list, nor a key or a rheology's name of 10^5 characters (a
    message as long as the input it quotes is not read)."""
    return text if len(text) <= SHOWN_CHARACTERS else text[: SHOWN_CHARACTERS - 3] + "..."


def shown(value: object) -> str:
    """``repr(value)`` :func:`shortened`, a numpy scalar written as the plain value it
    holds: an attribute of another tool's netCDF file is read as one, and a message said
    ``units np.float64(5.0)`` where the file says 5.0.  An integer of more digits than
    Python writes (``sys.get_int_max_str_digits``), or a value holding one, is described
    (its ``repr`` raised ``ValueError`` in the message's place)."""
    try:
        return shortened(repr(plain_scalar(value)))
    except ValueError:
        if isinstance(value, int):
            return f"an integer of about {math.ceil(value.bit_length() * math.log10(2))} digits"
        return (
            f"a {type(value).__name__} holding an integer of more than {sys.get_int_max_str_digits()} digits"
        )


def plain_scalar(value: object) -> object:
    """``value``, or the Python bool, int, float, complex, str or bytes a numpy scalar holds (a
    ``np.longdouble`` beyond the floats, a date or a duration stay as they are)."""
    kind = getattr(getattr(value, "dtype", None), "kind", None)
    if (
        type(value).__module__ != "numpy"
        or getattr(value, "shape", None) != ()
        or kind not in tuple("biufcSU")
    ):
        return value
    number = value.item()  # type: ignore[attr-defined]
    return number if type(number) in (bool, int, float, complex, str, bytes) else value


def printable(text: str) -> str:
    """``text`` with each character that is not printable but a newline or a tab written as
    Python writes it in a string (``\\x1b``, ``\\u202e``): a message quotes names from the
    input (a rheology, a file), and an escape sequence of the terminal there acted on it."""
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() or c in "\n\t" else repr(c)[1:-1] for c in text)


def warn(message: str, file: TextIO | None = None) -> None:
    """Say ``message`` as a warning of the command (``multilayer: warning: ...``) on
    ``file`` (default stderr, :func:`to_stderr`), its characters :func:`printable`."""
    text = printable(f"multilayer: warning: {message}")
    if file is None:
        to_stderr(text)
    else:
        print(text, file=file)


def to_stderr(text: str, *, flush: bool = False) -> None:
    """``text`` printed on ``sys.stderr``, or nowhere where the process has none (started
    with ``2>&-``, under pythonw): ``print(file=None)`` writes on stdout, where the lines
    of a command's output or the host process's own data are (``multilayer validate
    bad.yaml 2>&-`` wrote its error there).  Where ``sys.stderr`` was set to None since the
    start (a third-party law), the process's own stderr, ``sys.__stderr__``: the message of
    the run it stopped went nowhere."""
    stream = sys.stderr if sys.stderr is not None else sys.__stderr__
    if stream is not None:
        print(text, file=stream, flush=flush)
