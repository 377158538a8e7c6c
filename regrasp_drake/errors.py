"""One kind of error for bad user input, with a message that fits on one line."""


class InputError(ValueError):
    """Bad user input (a file, a field, a parameter).

    The message names the field, the value and what was expected, on one line,
    so that the command line can print it as is and exit non-zero.
    """


def field_error(field: str, value, expected: str) -> InputError:
    """Returns the InputError for `field` holding `value` where `expected` was."""
    return InputError(f"{field}: got {value!r}, expected {expected}")
