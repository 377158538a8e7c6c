"""A success map's rows on disk: JSON lines, one row per cell, appended as
each cell finishes (`open_rows`) and read back to resume (`read_rows`), with
the file beside them that says what they were computed from (`plan_path`).

Light on purpose (no Drake, no torch): the command line checks an existing
map before it loads either, so that bad input is refused at once.
"""

from pathlib import Path

from regrasp_drake.atomic_io import RowAppender
from regrasp_drake.errors import InputError, field_error, quote
from regrasp_drake.input_files import parse_json, read_text
from regrasp_drake.parameter_space import is_cell


def map_key(row) -> tuple[int, int]:
    """The cell of a success map's row; InputError for a row that is not
    one (no cell of the grid, no outcome)."""
    cell = row.get("cell") if isinstance(row, dict) else None
    if not (isinstance(cell, list) and is_cell(cell)):
        raise field_error("cell", cell, "[i_catch, i_down] of the grid")
    if not isinstance(row.get("outcome"), str):
        raise field_error("outcome", row.get("outcome"), "a string")
    return tuple(cell)


def read_rows(path: Path, key=map_key) -> dict:
    """{key(row): row} from a JSON-lines file (by default a success map's
    rows, keyed by cell: map_key). A last line cut by a kill (no newline at
    its end) is skipped (its work runs again); any other line that is not a
    row key() reads is refused (InputError naming the file and the line)."""
    done = {}
    path = Path(path)
    if not path.exists():
        return done
    lines = read_text(path, "JSON-lines file of rows").split("\n")
    for n, line in enumerate(lines, 1):
        if not line.strip():
            continue
        try:
            row = parse_json(line)
            k = key(row)
            hash(k)
        except (InputError, KeyError, TypeError, IndexError, ValueError) as e:
            if n == len(lines):  # no newline after it: cut by a kill
                continue
            reason = (str(e) if isinstance(e, InputError)
                      else f"{type(e).__name__} {quote(str(e))}")
            raise InputError(f"{path}: line {n}: not a whole row ({reason}), "
                             "expected one JSON row per line: delete the "
                             "line to compute it again, or give another "
                             "file") from None
        done[k] = row
    return done


def open_rows(path: Path) -> RowAppender:
    """The JSON-lines file at path, opened to append rows (`append(line)`,
    each fsynced). A last line cut by a kill (no newline at its end) is
    removed first, and a write that fails is cut back off, so that every
    line of the file stays a whole row (its work runs again; read_rows
    would skip it too)."""
    return RowAppender(path)


def plan_path(out: Path) -> Path:
    """The file beside a map's rows that says what they were computed from."""
    out = Path(out)
    return out.with_name(out.name + ".plan.json")
