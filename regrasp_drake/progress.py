"""The progress bars of the long commands (maps, data sets, benchmarks):
tqdm's, on stderr, drawn only when stderr is a terminal (tqdm's
disable=None), so that logs and piped output hold none of them."""

import sys

from tqdm import tqdm


def bar(total: int, label: str = "", unit: str = "cells", *,
        enabled: bool = True) -> tqdm:
    """A progress bar over `total` items of `unit`, labelled `label`; shown
    when `enabled` and stderr is a terminal. Use it as a context manager
    and call update() as each item finishes."""
    return tqdm(total=total, desc=label, unit=f" {unit}", file=sys.stderr,
                disable=None if enabled else True, dynamic_ncols=True,
                leave=True)


def iterate(items, total: int, label: str = "", unit: str = "items", *,
            enabled: bool = True):
    """Yields `items` (`total` of them) with a progress bar (`bar`) that
    advances as each one's work is done (when the loop asks for the next)."""
    with bar(total, label, unit, enabled=enabled) as shown:
        for item in items:
            yield item
            shown.update()


def say(text: str, file) -> None:
    """Writes a line of progress to `file` without breaking a bar drawn on
    the terminal (tqdm.write), flushed so that a piped log shows it at
    once."""
    tqdm.write(text, file=file)
    file.flush()
