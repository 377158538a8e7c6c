"""The wavefront order of the search over the parameter space (paper §V.A,
Figs. 7-8).

The search starts at the cell nearest the network's output, then visits
"sequential layers of neighbors" completely: ring 1 (the cells one unit away
in h_catch and/or h_down, Chebyshev distance 1), ring 2, and so on until the
150 cells are exhausted. Cells outside the 10 × 15 grid are skipped, so a ring
near an edge or a corner is shorter.

Inside a ring the order is fixed: nearest first by the Euclidean distance in
cell units (the four edge neighbours of a ring before its corners), then by
h_catch index, then by h_down index (both ascending: lower h_catch first,
more lowering first).
"""

from regrasp_drake.errors import field_error
from regrasp_drake.grid import H_CATCH_VALUES, H_DOWN_VALUES, cells

Cell = tuple[int, int]  # (i_catch, i_down): indices into grid.H_*_VALUES


def ring(cell: Cell, start: Cell) -> int:
    """The Chebyshev distance between two cells, in cell units: the ring of
    the wavefront around `start` that `cell` belongs to."""
    return max(abs(cell[0] - start[0]), abs(cell[1] - start[1]))


def wavefront_order(start_cell: Cell) -> list[Cell]:
    """Every cell of the grid once, in the search's order from start_cell
    (first), ring by ring, in the in-ring order of the module's docstring."""
    start = tuple(int(k) for k in start_cell)
    if not (len(start) == 2 and 0 <= start[0] < len(H_CATCH_VALUES)
            and 0 <= start[1] < len(H_DOWN_VALUES)):
        raise field_error("start_cell", start_cell,
                          f"(i_catch, i_down) with 0 <= i_catch < "
                          f"{len(H_CATCH_VALUES)} and 0 <= i_down < "
                          f"{len(H_DOWN_VALUES)}")

    def key(cell):
        di, dj = cell[0] - start[0], cell[1] - start[1]
        return ring(cell, start), di * di + dj * dj, cell[0], cell[1]

    return sorted(cells(), key=key)
