"""One kind of error for bad user input, with a message that fits on one line."""

import os
from pathlib import Path


class InputError(ValueError):
    """Bad user input (a file, a field, a parameter).

    The message names the field, the value and what was expected, on one line,
    so that the command line can print it as is and exit non-zero.
    """


def field_error(field: str, value, expected: str) -> InputError:
    """Returns the InputError for `field` holding `value` where `expected` was."""
    return InputError(f"{field}: got {value!r}, expected {expected}")


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
