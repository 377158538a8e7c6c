"""One kind of error for bad user input, with a message that fits on one line."""

import os
import reprlib
from pathlib import Path

# A quoted value is cut to this many characters: a message stays one short
# line even for a huge value, and quoting it never expands it.
QUOTE_CHARS = 60
_REPR = reprlib.Repr()
_REPR.maxlevel, _REPR.maxdict = 3, 4
_REPR.maxtuple = _REPR.maxlist = _REPR.maxset = _REPR.maxfrozenset = 6
_REPR.maxstring = _REPR.maxlong = _REPR.maxother = QUOTE_CHARS


class InputError(ValueError):
    """Bad user input (a file, a field, a parameter).

    The message names the field, the value and what was expected, on one line,
    so that the command line can print it as is and exit non-zero.
    """


def quote(value) -> str:
    """repr(value) in at most QUOTE_CHARS characters (a long one cut in the
    middle with "..."), computed without expanding a large value."""
    text = _REPR.repr(value).replace("\n", " ")
    if len(text) <= QUOTE_CHARS:
        return text
    half = (QUOTE_CHARS - 3) // 2
    return text[:half] + "..." + text[-half:]


def field_error(field: str, value, expected: str) -> InputError:
    """Returns the InputError for `field` holding `value` (quoted) where
    `expected` was."""
    return InputError(f"{field}: got {quote(value)}, expected {expected}")


def check_output_path(flag: str, path, *, makes_directory: bool = False) -> None:
    """Refuses, before any work, an output path that could not be written
    (InputError naming `flag`): a file's directory must exist and be
    writable; a directory the command makes (`makes_directory`) must lie
    under a writable one."""
    path = Path(path)
    if makes_directory:
        if path.exists() and not path.is_dir():
            raise InputError(f"{flag}: got {str(path)!r}, expected a "
                             "directory (it is a file)")
        directory = path
        while not directory.exists():
            directory = directory.parent
    else:
        if path.is_dir():
            raise InputError(f"{flag}: got {str(path)!r}, expected a "
                             "file path (it is a directory)")
        directory = path.parent
        if not directory.is_dir():
            raise InputError(f"{flag}: got {str(path)!r}, expected a "
                             "path in an existing directory")
    if not directory.is_dir() or not os.access(directory, os.W_OK):
        raise InputError(f"{flag}: got {str(path)!r}, expected a path "
                         f"under a writable directory ({str(directory)!r}"
                         " is not one)")


# Ctrl-C, remembered: Python runs its SIGINT handler wherever the main
# thread is, and a KeyboardInterrupt raised inside a hook that ignores
# exceptions (os.fork's at-fork hooks, logging's among them) is lost. The
# command's handler records it here; long loops call `check_interrupt` at
# safe points, so that a lost one is raised again there.
_interrupted = False


def note_interrupt(pressed: bool = True) -> None:
    """Records Ctrl-C (or, with False, forgets it: a new command starts)."""
    global _interrupted
    _interrupted = pressed


def check_interrupt() -> None:
    """Raises KeyboardInterrupt if Ctrl-C was pressed in this process."""
    if _interrupted:
        raise KeyboardInterrupt
