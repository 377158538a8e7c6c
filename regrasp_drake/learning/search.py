"""The searches over the parameter space: the paper's wavefront order (§V.A,
Figs. 7-8) and an optional map-prior search.

The wavefront search starts at the cell nearest the network's output, then visits
"sequential layers of neighbors" completely: ring 1 (the cells one unit away
in h_catch and/or h_down, Chebyshev distance 1), ring 2, and so on until the
150 cells are exhausted. Cells outside the 10 × 15 grid are skipped, so a ring
near an edge or a corner is shorter.

Inside a ring the order is fixed: nearest first by the Euclidean distance in
cell units (the four edge neighbours of a ring before its corners), then by
h_catch index, then by h_down index (both ascending: lower h_catch first,
more lowering first).

The map-prior search (`map_prior_order`, the learning phase's
`search="map-prior"`; the wavefront is the paper's and the default) orders
the cells by what the training success maps say about an unseen object's
map instead of by distance alone. It starts at the same cell (the network's).
Each training map m (models/dataset/maps.npz, `load_prior_maps`) is smoothed
into P_m, the map convolved with a Gaussian of SIGMA_CELLS cells (radius 2
cells, the grid's edges repeated outwards): a cell next to catching cells
counts as likely to catch. Every map starts with weight w_m = 1; after each
failed cell c,

    w_m *= EPS + (1 - 2 EPS) * (1 - P_m[c])

(the likelihood of the failure if the object's map were m, read as an
observation that is wrong with probability EPS, so that no map is ever ruled
out by one cell), and the next cell is the untried cell with the largest
posterior mean sum_m w_m P_m[c] / sum_m w_m, ties (to 1e-9) going to the
earlier cell in the wavefront order from the start. Each cell is tried at
most once and all 150 eventually.

Source: an offline evaluation on the training maps (96 maps, 48 objects,
two catch points each), leave-one-object-out (both catch points of the held
out object removed from the prior), from the start cell (7, 2) (the
network's cell for table1 rows 1-3): over the 90 held-out maps that catch
somewhere, 8.48 cells tried on average to the first catch with the
wavefront, 4.10 with the map prior; caught within 3 cells 0.844 and 0.878.
EPS 0.1-0.3 and SIGMA_CELLS 0-1.0 were tried; 0.2 and 0.7 gave the fewest
cells on average, chosen on these same maps (so 4.10 is slightly
optimistic). The mean hides a long tail: one held-out map
(bottle-d250-4@2) costs the map prior 96 cells. Started instead at the label
cell of the object's other catch point, the map prior catches more often
within 2-3 cells (0.909/0.920 vs 0.864/0.886) but needs more cells on average
(3.71 vs 2.99, that same map). On the stored Table 1 maps, from the
network's cells, table1-row4 takes 9 cells instead of 60 and the other rows
1 with both; `regrasp-drake table1 --search map-prior` gave the same throws.
`benchmarks/search_prior.py` recomputes these figures. In the other modes
(models/results/*_prior.json): at release, table1-row4 in 9 throws (the
wavefront: not within 8); on the held-out objects holdout-dumbbell-d300 in
3 / 3 / 2 throws watching first / first-throw / at release (the wavefront
6 / 6 / 5); every other object in as many throws as with the wavefront.
"""

import zipfile
from pathlib import Path

import numpy as np

from regrasp_drake.errors import field_error
from regrasp_drake.grid import H_CATCH_VALUES, H_DOWN_VALUES, cells
from regrasp_drake.paths import MODELS_DIR

Cell = tuple[int, int]  # (i_catch, i_down): indices into grid.H_*_VALUES
SHAPE = (len(H_CATCH_VALUES), len(H_DOWN_VALUES))  # (i_catch, i_down)

SEARCHES = ("wavefront", "map-prior")  # the learning phase's `search`
PRIOR_MAPS_PATH = MODELS_DIR / "dataset" / "maps.npz"  # the shipped prior
# The map-prior search's constants (see the module's docstring):
EPS = 0.2            # chance that a cell's outcome contradicts a map, [1]
SIGMA_CELLS = 0.7    # the smoothing Gaussian's standard deviation, [cells]
                     # (0.028 m in h_catch, 0.007 m in h_down)
SMOOTHING_RADIUS = 2  # the smoothing kernel's half-width, [cells]


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


def load_prior_maps(path=PRIOR_MAPS_PATH) -> tuple[list[str], np.ndarray]:
    """The training success maps of a data set's maps.npz (`regrasp-drake
    dataset`): the entry names (`<object>` or `<object>@k`, see
    learning/dataset.py) and the maps, a boolean array (entries, 10, 15)
    indexed (entry, i_catch, i_down), True where the cell catches. A missing
    or malformed file is refused with one line naming it."""
    path = Path(path)
    expected = (f"a data set's maps.npz with 'objects' (entry names) and "
                f"'caught' (entries x {SHAPE[0]} x {SHAPE[1]} booleans), as "
                "`regrasp-drake dataset` writes")
    if not path.is_file():
        raise field_error("prior maps", str(path), f"an existing file: {expected}")
    if not zipfile.is_zipfile(path):
        raise field_error("prior maps", str(path),
                          f"{expected} (the file is not an .npz archive)")
    try:
        with np.load(path, allow_pickle=False) as data:
            names = [str(n) for n in data["objects"]]
            caught = np.asarray(data["caught"])
    except Exception as e:  # not an npz, a key missing, pickled objects
        reason = f"{type(e).__name__}: {e}".replace("\n", " ")
        raise field_error("prior maps", str(path),
                          f"{expected} ({reason})") from None
    if (caught.ndim != 3 or caught.shape[1:] != SHAPE or caught.dtype != bool
            or len(names) != len(caught) or len(caught) == 0):
        raise field_error("prior maps", str(path),
                          f"{expected} (got {len(names)} names and 'caught' "
                          f"of shape {caught.shape}, dtype {caught.dtype})")
    return names, caught


def smooth(maps: np.ndarray, sigma_cells: float = SIGMA_CELLS) -> np.ndarray:
    """Each map (..., 10, 15) convolved with a Gaussian of sigma_cells
    (cells) along both axes, radius SMOOTHING_RADIUS cells, the edge cells
    repeated outwards; the kernel sums to 1, so values stay in [0, 1]. A
    sigma of 0 returns the maps as floats."""
    out = np.asarray(maps, float)
    if sigma_cells == 0:
        return out.copy()
    r = SMOOTHING_RADIUS
    x = np.arange(-r, r + 1)
    kernel = np.exp(-x ** 2 / (2 * sigma_cells ** 2))
    kernel /= kernel.sum()
    for axis in (-2, -1):
        n = out.shape[axis]
        pad = [(0, 0)] * out.ndim
        pad[axis] = (r, r)
        padded = np.pad(out, pad, mode="edge")
        out = sum(k * np.take(padded, range(t, t + n), axis=axis)
                  for t, k in enumerate(kernel))
    return out


def map_prior_order(start_cell: Cell, prior_maps, *, eps: float = EPS,
                    sigma_cells: float = SIGMA_CELLS):
    """The map-prior search from start_cell (see the module's docstring): a
    generator of cells, start_cell first. Each cell it yields is taken to
    have failed when the next one is asked for, as the learning phase does
    (it asks only after a failed throw). Every cell once, 150 in all.

    prior_maps: (entries, 10, 15) success maps (booleans, or catch
    probabilities in [0, 1]) indexed (entry, i_catch, i_down). eps: the
    chance that an outcome contradicts a map, in (0, 0.5]. sigma_cells: the
    smoothing Gaussian's standard deviation in cells, >= 0."""
    order = wavefront_order(start_cell)  # refuses a start outside the grid
    maps = np.asarray(prior_maps, float)
    if maps.ndim != 3 or maps.shape[1:] != SHAPE or len(maps) == 0:
        raise field_error("prior_maps", f"an array of shape {maps.shape}",
                          f"(entries >= 1, {SHAPE[0]}, {SHAPE[1]})")
    if not np.all((maps >= 0) & (maps <= 1)):
        raise field_error("prior_maps", "values outside [0, 1]",
                          "catch outcomes or probabilities in [0, 1]")
    if not 0 < eps <= 0.5:
        raise field_error("eps", eps, "a probability in (0, 0.5]")
    if not sigma_cells >= 0:
        raise field_error("sigma_cells", sigma_cells, "a length >= 0 cells")
    return _map_prior_cells(order, smooth(maps, sigma_cells), eps)


def _map_prior_cells(order: list[Cell], P: np.ndarray, eps: float):
    """The generator behind map_prior_order (its checks run when it is
    called, not at the first next())."""
    untried = list(order)       # kept in wavefront order: max() takes the
    w = np.ones(len(P))         # first of equal cells, the tie rule
    cell = order[0]
    while True:
        yield cell
        untried.remove(cell)
        if not untried:
            return
        w *= eps + (1 - 2 * eps) * (1 - P[:, cell[0], cell[1]])
        w /= w.sum()  # no underflow after many failures (each factor >= eps)
        posterior = np.tensordot(w, P, axes=1)
        cell = max(untried, key=lambda c: round(float(posterior[c]), 9))


def attempts_to_catch(order, caught) -> int | None:
    """How many cells of the search `order` (an iterable of cells) are tried
    up to and including the first that catches in `caught` (a boolean map,
    10 x 15, indexed (i_catch, i_down)); None if no cell catches."""
    caught = np.asarray(caught, bool)
    for n, cell in enumerate(order, 1):
        if caught[cell]:
            return n
    return None
