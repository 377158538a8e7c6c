"""The label of a success map (paper §IV.C): the catching cell most robust
to error.

    robustness(c) = the Chebyshev distance (in cells) from c to the nearest
                    cell that does not catch (cells beyond the grid's edge
                    are not failures; a map with no failure gives every
                    catching cell the largest distance, 15).
    label = argmax robustness over the catching cells; ties go to the cell
            nearest (Euclidean, in cells) to the mean of the tied cells, then
            to the lowest (h_catch index, h_down index).

A map none of whose cells catches has no label.
"""

import numpy as np

from regrasp_drake.parameter_space import H_CATCH_VALUES, H_DOWN_VALUES

SHAPE = (len(H_CATCH_VALUES), len(H_DOWN_VALUES))
LABEL_RULE = ("most robust catching cell (Chebyshev distance to the nearest "
              "failed cell); ties: nearest the tied cells' mean, then lowest "
              "indices")


def robustness(caught: np.ndarray) -> np.ndarray:
    """Per cell, the Chebyshev distance (cells) to the nearest failed cell;
    0 for failed cells. `caught`: a boolean array of SHAPE."""
    failed = np.argwhere(~caught)
    out = np.zeros(caught.shape, int)
    for i, j in np.argwhere(caught):
        if len(failed) == 0:
            out[i, j] = max(caught.shape)
        else:
            out[i, j] = int(np.min(np.maximum(np.abs(failed[:, 0] - i),
                                              np.abs(failed[:, 1] - j))))
    return out


def label_cell(caught: np.ndarray) -> tuple[int, int] | None:
    """The label of a success map (see above), or None."""
    r = robustness(caught)
    if r.max() == 0:
        return None
    best = np.argwhere(r == r.max())
    mean = best.mean(axis=0)
    key = [(float(np.sum((c - mean) ** 2)), int(c[0]), int(c[1])) for c in best]
    _, i, j = min(key)
    return (i, j)
