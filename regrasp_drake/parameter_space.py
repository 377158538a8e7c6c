"""The parameter space of the paper's §V.A: its values, cells and endings.

150 cells: 15 values of h_down (-0.14 … 0.00 m in steps of 0.01, the paper's
tolerance) times 10 values of h_catch (0.04 … 0.40 m in steps of 0.04). The
paper gives h_catch in [0, 0.40] with a tolerance of 0.04 and 10 states: the
10 states are 0.04 … 0.40 (h_catch = 0 would close the fingers only once the
object touches the palm). h_down: the paper's [-0.14, -0.01] with 0.01 gives 14
states for its 15; we add 0.00 (no lowering), as its Fig. 9 allows.

A cell is (i_catch, i_down), indices into H_CATCH_VALUES and H_DOWN_VALUES.
This module imports nothing from the package: the success maps (grid.py),
the data set, the search and the plots all build on it.
"""

import numpy as np

# The bounds of the parameters, [m].
H_CATCH_RANGE = (0.0, 0.40)
H_DOWN_RANGE = (-0.14, 0.0)
# The grid's values within them.
H_DOWN_VALUES = np.round(np.arange(-0.14, 0.001, 0.01), 2)    # 15, [m]
H_CATCH_VALUES = np.round(np.arange(0.04, 0.401, 0.04), 2)    # 10, [m]


def cells() -> list[tuple[int, int]]:
    """All (i_catch, i_down) cells, row-major in h_catch."""
    return [(i, j) for i in range(len(H_CATCH_VALUES))
            for j in range(len(H_DOWN_VALUES))]


def is_cell(cell) -> bool:
    """Whether `cell` is a cell of the grid: two ints (not bools), each
    within its axis."""
    return (isinstance(cell, (list, tuple)) and len(cell) == 2
            and all(type(k) is int for k in cell)
            and 0 <= cell[0] < len(H_CATCH_VALUES)
            and 0 <= cell[1] < len(H_DOWN_VALUES))


def cell_parameters(cell) -> tuple[float, float]:
    """(h_catch, h_down) of a cell, [m]."""
    i, j = cell
    return float(H_CATCH_VALUES[i]), float(H_DOWN_VALUES[j])


def nearest_cell(h_catch: float, h_down: float) -> tuple[int, int]:
    """The cell whose values are nearest (h_catch, h_down), [m]."""
    return (int(np.argmin(np.abs(H_CATCH_VALUES - h_catch))),
            int(np.argmin(np.abs(H_DOWN_VALUES - h_down))))


# The outcomes in which the hand holds the object at the end: "caught" (in
# the scenario's target grasp, planning/grasp.py; any grasp for target
# "any") and "wrong_grasp" (held in another).
HELD_OUTCOMES = ("caught", "wrong_grasp")

# How a cell's episode ended: the keys grid.ending gives a map row (from its
# outcome, the grasp monitor's drop reason and the bodies the object touches
# at the end), and what each means.
ENDINGS = {
    "caught": "caught (in the target grasp, for a regrasp target)",
    "wrong_grasp": "held, but not in the target grasp",
    "in_fingers": "not held: in the fingers, no grasp recognized by the "
                  "palm sensors, the bumper or the fingers' servos",
    "on_arm": "not held: at rest against the arm, no finger touching",
    "loose": "not held: neither in the fingers nor against the arm",
    "below_palm": "fell below the palm",
    "near_ground": "fell near the ground",
    "failed": "failed: a commanded pose out of the arm's reach (the lowered "
              "pose, mostly), or a failed contact solve",
    "other": "a timeout, or a row written without a drop reason",
}
