"""The searches over the parameter space: the paper's wavefront order (§V.A,
Figs. 7-8) and an optional map-prior search.

A search is an object, `Search`: it proposes a cell, is told how the throw
there ended, and proposes the next (the learning phase's loop,
learning_phase.learn); `map_prior_order` and `wavefront_order` give the
order it would try the cells in on a map where none catches.

The wavefront search starts at the cell nearest the network's output, then visits
"sequential layers of neighbors" completely: ring 1 (the cells one unit away
in h_catch and/or h_down, Chebyshev distance 1), ring 2, and so on until the
150 cells are exhausted. Cells outside the 10 × 15 grid are skipped, so a ring
near an edge or a corner is shorter.

Inside a ring the order is fixed: nearest first by the Euclidean distance in
cell units (the four edge neighbours of a ring before its corners), then by
h_catch index, then by h_down index (both ascending: lower h_catch first,
more lowering first).

The map-prior search (a Search with a `MapPrior`, the learning phase's
`search="map-prior"`; the wavefront is the paper's and the default) orders
the cells by what the training success maps say about an unseen object's
map instead of by distance alone. It starts at the same cell (the network's).
Each training map m (models/dataset/maps.npz, `load_prior_maps`) is smoothed
into P_m, the map convolved with a Gaussian of SIGMA_CELLS cells (radius 2
cells, the grid's edges repeated outwards): a cell next to catching cells
counts as likely to catch. Map m starts with the weight w_m of its entry's
network features f_m (v_catch, h_cm, r_cm, d_obj, v_conv) seen from the
object's features f (`feature_weights`):

    w_m = exp(-|z(f_m) - z(f)|^2 / (2 FEATURE_SIGMA^2)),

z dividing each feature's deviation from the prior's mean by the prior's
standard deviation, so that maps of objects like this one count most (all
weights 1 when FEATURE_SIGMA is None, or without features). After each
failed cell c,

    w_m *= EPS + (1 - 2 EPS) * (1 - P_m[c])

(the likelihood of the failure if the object's map were m, read as an
observation that is wrong with probability EPS, so that no map is ever ruled
out by one cell), and the next cell is the untried cell with the largest
posterior mean sum_m w_m P_m[c] / sum_m w_m, ties (to 1e-9) going to the
earlier cell in the wavefront order from the start. Each cell is tried at
most once and all 150 eventually.

Source: `studies/search_prior/search_prior.py` (search_prior.json), offline on the
training maps (222 maps: 56 objects, four catch points each),
leave-one-object-out (every catch point of the held-out object removed from
the prior), from the start cell (7, 2): over the 181 held-out maps that
catch somewhere, the cells tried to the first catch on average, and the
share caught within 2 and within 3 cells (2 cells: the paper's 3 throws,
the watch included):

    wavefront (the paper's)                  9.18   0.801   0.829
    map prior, every map alike (shipped)     3.86   0.851   0.873
    map prior, feature kernel of width 0.75  5.79   0.845   0.873

EPS and SIGMA_CELLS were chosen on the 96 maps of the 48 objects of an
earlier data set, with every map alike (0.2 and 0.7 of EPS 0.1-0.3 and
SIGMA_CELLS 0-1.0: the fewest cells on average), FEATURE_SIGMA on these
same maps (see it), so the figures are slightly optimistic. On the stored
Table 1 maps, from the network's cells, table1-row4 takes 14 cells
(wavefront 50, the kernel of width 0.75 2) and the other rows 1 with every
search; `regrasp-drake table1 --search map-prior` gave the same throws
(row 4's 15 with --max-throws 40; models/results/table1_prior.json, made
with --max-throws 12, stops it at 12).
The other modes: README, "Table 1, held-out objects, noise".
"""

import io
import zipfile
from pathlib import Path

import numpy as np

from regrasp_drake.errors import InputError, field_error, quote
from regrasp_drake.input_files import read_bytes
from regrasp_drake.parameter_space import H_CATCH_VALUES, H_DOWN_VALUES, cells
from regrasp_drake.paths import MODELS_DIR

# A maps.npz unpacks to at most this many bytes (the shipped one, 222
# entries, to some 60 kB).
_MAX_UNPACKED_BYTES = 64 * 1024 * 1024
Cell = tuple[int, int]  # (i_catch, i_down): indices into H_*_VALUES
SHAPE = (len(H_CATCH_VALUES), len(H_DOWN_VALUES))  # (i_catch, i_down)

SEARCHES = ("wavefront", "map-prior")  # the learning phase's `search`
NUM_FEATURES = 5  # the network's inputs (dataset_files.FEATURE_NAMES)
PRIOR_MAPS_PATH = MODELS_DIR / "dataset" / "maps.npz"  # the shipped prior
# The map-prior search's constants (see the module's docstring):
EPS = 0.2            # chance that a cell's outcome contradicts a map, [1]
SIGMA_CELLS = 0.7    # the smoothing Gaussian's standard deviation, [cells]
                     # (0.028 m in h_catch, 0.007 m in h_down)
SMOOTHING_RADIUS = 2  # the smoothing kernel's half-width, [cells]
# The feature kernel's width, in standard deviations of the prior's
# features: of None (uniform), 4, 3, 2, 1.5, 1, 0.75 and 0.5, the one whose
# leave-one-object-out search on the training maps (from the cell (7, 2))
# catches most often within 2 cells (the paper's 3 throws), ties going to
# more often within 3 cells; studies/search_prior/search_prior.py, "feature_sigma".
# On the 222 maps of four catch points per object that is None (0.851 and
# 0.873 within 2 and 3 cells; 0.75, the choice on the 112 maps of two
# catch points, 0.845 and 0.873): every map weighs alike.
FEATURE_SIGMA = None


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


def load_prior_maps(path=PRIOR_MAPS_PATH, *, with_features: bool = False):
    """The training success maps of a data set's maps.npz (`regrasp-drake
    dataset`): the entry names (`<object>` or `<object>@k`, see
    learning/dataset_files.py) and the maps, a boolean array (entries, 10, 15)
    indexed (entry, i_catch, i_down), True where the cell catches; with
    `with_features`, also the entries' network features (entries, 5), or
    None for a file written without them. A missing or malformed file is
    refused with one line naming it."""
    path = Path(path)
    expected = (f"a data set's maps.npz with 'objects' (entry names) and "
                f"'caught' (entries x {SHAPE[0]} x {SHAPE[1]} booleans), as "
                "`regrasp-drake dataset` writes")
    if not path.is_file():
        raise field_error("prior maps", str(path), f"an existing file: {expected}")
    try:  # a regular file of at most input_files.MAX_FILE_BYTES
        raw = io.BytesIO(read_bytes(path, "data set's maps.npz"))
    except InputError as e:
        raise field_error("prior maps", str(path), f"{expected} ({e})") from None
    if not zipfile.is_zipfile(raw):
        raise field_error("prior maps", str(path),
                          f"{expected} (the file is not an .npz archive)")
    try:
        with zipfile.ZipFile(raw) as archive:  # no "zip bomb" unpacked
            unpacked = sum(info.file_size for info in archive.infolist())
        if unpacked > _MAX_UNPACKED_BYTES:
            raise ValueError(f"its arrays unpack to {unpacked} bytes, more "
                             f"than {_MAX_UNPACKED_BYTES}")
        raw.seek(0)
        with np.load(raw, allow_pickle=False) as data:
            names = [str(n) for n in data["objects"]]
            caught = np.asarray(data["caught"])
            features = (np.asarray(data["features"], float)
                        if "features" in data.files else None)
    except Exception as e:  # not an npz, a key missing, pickled objects
        reason = f"{type(e).__name__}: {quote(str(e))}"
        raise field_error("prior maps", str(path),
                          f"{expected} ({reason})") from None
    if (caught.ndim != 3 or caught.shape[1:] != SHAPE or caught.dtype != bool
            or len(names) != len(caught) or len(caught) == 0):
        raise field_error("prior maps", str(path),
                          f"{expected} (got {len(names)} names and 'caught' "
                          f"of shape {caught.shape}, dtype {caught.dtype})")
    if features is not None and (features.shape != (len(names), NUM_FEATURES)
                                 or not np.all(np.isfinite(features))):
        raise field_error("prior maps", str(path),
                          f"{expected}; its 'features' finite and of shape "
                          f"({len(names)}, {NUM_FEATURES}) (got "
                          f"{features.shape})")
    if with_features:
        return names, caught, features
    return names, caught


def feature_weights(features, prior_features,
                    sigma: float | None = FEATURE_SIGMA) -> np.ndarray:
    """Each prior map's starting weight for an object with network features
    `features` (5, FEATURE_NAMES order) when the maps' entries had
    `prior_features` (entries, 5): the Gaussian kernel of the module's
    docstring, scaled so that the nearest entry weighs 1 (no underflow).
    sigma None: every weight 1."""
    prior = np.asarray(prior_features, float)
    f = np.asarray(features, float)
    if prior.ndim != 2 or prior.shape[1] != NUM_FEATURES or len(prior) == 0:
        raise field_error("prior_features", f"an array of shape {prior.shape}",
                          f"(entries >= 1, {NUM_FEATURES})")
    if f.shape != (NUM_FEATURES,) or not np.all(np.isfinite(f)):
        raise field_error("features", f.tolist(),
                          f"{NUM_FEATURES} finite numbers")
    if sigma is None:
        return np.ones(len(prior))
    if not sigma > 0:
        raise field_error("sigma", sigma, "a width > 0 (standard deviations)"
                          " or None")
    std = prior.std(axis=0)
    std = np.where(std > 1e-12, std, 1.0)  # a feature all entries share
    d2 = np.sum(((prior - f) / std) ** 2, axis=1)
    return np.exp(-(d2 - d2.min()) / (2 * sigma ** 2))


def smooth(maps: np.ndarray, sigma_cells=SIGMA_CELLS) -> np.ndarray:
    """Each map (..., 10, 15) convolved with a Gaussian of sigma_cells
    (cells) along both axes (or a pair: along h_catch, along h_down),
    radius SMOOTHING_RADIUS cells, the edge cells repeated outwards; the
    kernel sums to 1, so values stay in [0, 1]. A sigma of 0 leaves that
    axis as it is; the maps come back as floats."""
    out = np.asarray(maps, float)
    sigmas = (tuple(sigma_cells) if np.ndim(sigma_cells)
              else (sigma_cells, sigma_cells))
    if not any(sigmas):
        return out.copy()
    r = SMOOTHING_RADIUS
    x = np.arange(-r, r + 1)
    for axis, sigma in zip((-2, -1), sigmas):
        if sigma == 0:
            continue
        kernel = np.exp(-x ** 2 / (2 * sigma ** 2))
        kernel /= kernel.sum()
        n = out.shape[axis]
        pad = [(0, 0)] * out.ndim
        pad[axis] = (r, r)
        padded = np.pad(out, pad, mode="edge")
        out = sum(k * np.take(padded, range(t, t + n), axis=axis)
                  for t, k in enumerate(kernel))
    return out


class MapPrior:
    """The map-prior search's belief (see the module's docstring): the
    smoothed training maps P_m and each map's weight w_m, which every failed
    cell updates (`fail`); `most_likely` picks the next cell.

    prior_maps: (entries, 10, 15) success maps (booleans, or catch
    probabilities in [0, 1]) indexed (entry, i_catch, i_down). eps: the
    chance that an outcome contradicts a map, in (0, 0.5]. sigma_cells: the
    smoothing Gaussian's standard deviation in cells, >= 0 (or a pair, see
    `smooth`). weights: each map's starting weight (entries, >= 0, not all
    0; `feature_weights`), or None for all 1. observed(cell), optional:
    each map's probability of what was seen at a failed cell (default
    1 - P_m[cell]: that it did not catch)."""

    def __init__(self, prior_maps, *, eps: float = EPS,
                 sigma_cells: float = SIGMA_CELLS, weights=None,
                 observed=None):
        maps = np.asarray(prior_maps, float)
        if maps.ndim != 3 or maps.shape[1:] != SHAPE or len(maps) == 0:
            raise field_error("prior_maps", f"an array of shape {maps.shape}",
                              f"(entries >= 1, {SHAPE[0]}, {SHAPE[1]})")
        if not np.all((maps >= 0) & (maps <= 1)):
            raise field_error("prior_maps", "values outside [0, 1]",
                              "catch outcomes or probabilities in [0, 1]")
        if not 0 < eps <= 0.5:
            raise field_error("eps", eps, "a probability in (0, 0.5]")
        if not np.all(np.asarray(sigma_cells) >= 0):
            raise field_error("sigma_cells", sigma_cells,
                              "a length >= 0 cells")
        w = (np.ones(len(maps)) if weights is None
             else np.array(weights, float))
        if (w.shape != (len(maps),) or not np.all(np.isfinite(w))
                or np.any(w < 0) or not w.sum() > 0):
            raise field_error("weights", f"an array of shape {w.shape}",
                              f"{len(maps)} finite weights >= 0, not all 0")
        self.P = smooth(maps, sigma_cells)
        self.w = w
        self.eps = eps
        self.observed = observed

    def fail(self, cell: Cell) -> None:
        """Updates the weights with a failure at `cell`."""
        seen = (1 - self.P[:, cell[0], cell[1]] if self.observed is None
                else self.observed(cell))
        self.w *= self.eps + (1 - 2 * self.eps) * seen
        self.w /= self.w.sum()  # no underflow after many failures (>= eps)

    def most_likely(self, candidates: list[Cell]) -> Cell:
        """The candidate with the largest posterior mean catch probability;
        of equal ones (to 1e-9), the first."""
        posterior = np.tensordot(self.w, self.P, axes=1)
        return max(candidates, key=lambda c: round(float(posterior[c]), 9))


def object_prior(prior_maps, prior_features, features,
                 sigma: float | None = FEATURE_SIGMA) -> MapPrior:
    """The map prior of an object with network features `features`: each
    prior map first weighted by feature_weights(features, prior_features,
    sigma); prior_features None (a prior without features): every map
    alike."""
    weights = (None if prior_features is None
               else feature_weights(features, prior_features, sigma))
    return MapPrior(prior_maps, weights=weights)


class Search:
    """One search over the grid's cells from a start cell (the network's):
    it proposes a cell (`next_cell`), is told how the throw there ended
    (`tell`), and proposes the next, until a cell catches or every cell has
    been tried. Each cell is tried at most once.

    Without a prior it is the paper's wavefront search: the cells in
    `wavefront_order(start_cell)`. With a MapPrior it is the map-prior
    search: after each failure, the untried cell the prior finds most likely
    to catch (ties to the earlier in the wavefront order).

    reach, optional: per h_down of the grid, whether the arm reaches the
    lowered pose (`throw_catch.reachable_h_down`). A cell of a column it
    does not reach fails whatever the object does: it is passed over
    without a throw, recorded as "unreachable" (a failure to the map
    prior, as it would be).

    State: `order`, the wavefront from the start (every cell once);
    `tried`, each cell tried and its outcome, in order; `next_cell`, the
    cell to try next (None once one caught or none is left); the prior's
    weights."""

    UNREACHABLE = "unreachable"  # the outcome of a cell passed over

    def __init__(self, start_cell: Cell, prior: MapPrior | None = None, *,
                 reach=None):
        self.order = wavefront_order(start_cell)  # refuses a start outside
        self.start = self.order[0]
        self.prior = prior
        self.reach = None if reach is None else list(reach)
        if self.reach is not None and len(self.reach) != SHAPE[1]:
            raise field_error("reach", self.reach,
                              f"{SHAPE[1]} booleans, one per h_down")
        self.tried: list[tuple[Cell, str]] = []
        self._untried = list(self.order)  # in wavefront order: the tie rule
        self.next_cell: Cell | None = self._passing_unreachable(self.start)

    @property
    def caught(self) -> bool:
        """Whether a cell caught."""
        return bool(self.tried) and self.tried[-1][1] == "caught"

    def tell(self, outcome: str) -> None:
        """How the throw at next_cell ended ("caught", or how it failed);
        the search then proposes its next cell."""
        if self.next_cell is None:
            raise field_error("outcome", outcome, "none: the search is over "
                              "(a cell caught or every cell was tried)")
        self._record(self.next_cell, outcome)
        self.next_cell = (None if outcome == "caught"
                          else self._passing_unreachable(self._choose()))

    def __iter__(self):
        """The cells proposed one after another, each taken to have failed
        when the next is asked for (the learning phase asks for another
        cell only after a failed throw): up to the first that catches,
        `attempts_to_catch`; all of them, the order on a map where none
        does."""
        while self.next_cell is not None:
            yield self.next_cell
            self.tell("failed")

    def _record(self, cell: Cell, outcome: str) -> None:
        self.tried.append((cell, outcome))
        self._untried.remove(cell)
        if outcome != "caught" and self.prior is not None:
            self.prior.fail(cell)

    def _choose(self) -> Cell | None:
        if not self._untried:
            return None
        if self.prior is None:
            return self._untried[0]
        return self.prior.most_likely(self._untried)

    def _passing_unreachable(self, cell: Cell | None) -> Cell | None:
        """cell, or if the arm cannot reach it, the next cell the search
        proposes that it reaches (those passed over recorded)."""
        while (cell is not None and self.reach is not None
               and not self.reach[cell[1]]):
            self._record(cell, self.UNREACHABLE)
            cell = self._choose()
        return cell


def map_prior_order(start_cell: Cell, prior_maps, *, eps: float = EPS,
                    sigma_cells: float = SIGMA_CELLS, weights=None):
    """The map-prior search from start_cell (see MapPrior and Search): an
    iterator of cells, start_cell first, each taken to have failed when the
    next one is asked for. Every cell once, 150 in all. Bad arguments are
    refused when it is called."""
    return iter(Search(start_cell, MapPrior(
        prior_maps, eps=eps, sigma_cells=sigma_cells, weights=weights)))


def feature_weighted_order(start_cell: Cell, prior_maps, prior_features,
                           features, sigma: float | None = FEATURE_SIGMA):
    """map_prior_order from start_cell with the map prior of an object with
    network features `features` (`object_prior`)."""
    return iter(Search(start_cell, object_prior(prior_maps, prior_features,
                                                features, sigma)))


def attempts_to_catch(order, caught) -> int | None:
    """How many cells of the search `order` (an iterable of cells) are tried
    up to and including the first that catches in `caught` (a boolean map,
    10 x 15, indexed (i_catch, i_down)); None if no cell catches."""
    caught = np.asarray(caught, bool)
    for n, cell in enumerate(order, 1):
        if caught[cell]:
            return n
    return None
