"""The learned planner (issue 55): a model of a catch's success over
everything a data set's map shows, and the choice of highest predicted
success, judged against the paper's network, the best constant cell and
each map's best cell.

The model, `SuccessModel`: for an object, its planned catch and a cell of
the parameter space, the probability that the catch ends in the data set's
target grasp. Its inputs are PLANNER_FEATURES (the paper's five, what the
catalogue says of the object's mass and shape, the catch point of its
watched or predicted flight, and where the palm waits relative to the
object), standardized by the training maps' means and deviations, and the
cell's two indices scaled to [0, 1]. Every cell of every training map is a
sample (the paper's network learns from one label per map): a two-layer
tanh perceptron trained on the cross entropy of the cells' outcomes by
full-batch Adam, the mean of MEMBERS networks of different initial
weights. The planner takes the reachable cell of highest predicted success
(`choose`). One model per target: the targets' throws differ (the flip's
spin, the keep's none) and their maps too, and a model per data set is
judged on the same maps as its baselines.

Judged honestly (`judge`): on splits by geometry (every object of one
geometry held out, trained on the others: a shape never seen) and by
object (one object held out), each held-out map scores the cell each
chooser picks for it, against:
  - paper_network: the paper's 5-13-2 network (station/mlp_system.py)
    trained on the training maps' labels (learning/labels.py), its output's
    nearest cell;
  - best_constant: the cell that succeeds on the most training maps;
  - ceiling: the held-out map's best cell (1 when any cell succeeds).
"""

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from regrasp_drake import atomic_io
from regrasp_drake.errors import InputError, field_error
from regrasp_drake.input_files import load_tagged_json
from regrasp_drake.learning.dataset_files import FEATURE_NAMES, read_plan
from regrasp_drake.learning.labels import SHAPE, label_cell
from regrasp_drake.learning.provenance import load_provenance
from regrasp_drake.learning.search import load_prior_maps
from regrasp_drake.learning.train import fit
from regrasp_drake.parameter_space import cell_parameters, nearest_cell
from regrasp_drake.paths import MODELS_DIR, REPO_DIR
from regrasp_drake.station.mlp_system import CatchMlp
from regrasp_drake.station.scenario import load_scenario, target_of
from regrasp_drake.world.objects import ObjectSpec, resolve_object

# The model's inputs beside the cell: the paper's five; the object's mass
# and grasp piece (length, radius) and its largest and smallest central
# moments of inertia; the catch point (its time, height and tilt); where
# the palm waits, from the object's origin in the world frame, and on which
# side (+1 the paper's, -1 mirrored).
PLANNER_FEATURES = (*FEATURE_NAMES, "mass_kg", "grasp_length_m",
                    "grasp_radius_m", "inertia_max_kg_m2", "inertia_min_kg_m2",
                    "t_catch_s", "z_catch_m", "tilt", "palm_dx_m",
                    "palm_dy_m", "palm_dz_m", "side")
HIDDEN = 32
MEMBERS = 2
EPOCHS = 300
LEARNING_RATE = 0.01
WEIGHT_DECAY = 1e-3
# The choosers `judge` scores, in the report's order.
CHOOSERS = ("learned", "paper_network", "best_constant", "ceiling")

_FORMAT = "regrasp_drake.SuccessModel"


def planner_features(obj: ObjectSpec, plan: dict) -> list[float]:
    """PLANNER_FEATURES of an object and its catch plan (CatchPlan.as_dict:
    as a data set's plans/<entry>.json holds it)."""
    point = plan["catch_point"]
    inertia = np.linalg.eigvalsh(
        obj.spatial_inertia().Shift(obj.p_OCm).CalcRotationalInertia()
        .CopyToFullMatrix3())
    palm = np.asarray(plan["p_WG"], float) - np.asarray(point["p_WO"], float)
    values = {"v_catch": point["v_catch"]} | obj.features() | {
        "mass_kg": obj.mass, "grasp_length_m": obj.grasp_length,
        "grasp_radius_m": obj.grasp_radius,
        "inertia_max_kg_m2": inertia[-1], "inertia_min_kg_m2": inertia[0],
        "t_catch_s": point["t_s"], "z_catch_m": point["p_WO"][2],
        "tilt": point["tilt"], "palm_dx_m": palm[0], "palm_dy_m": palm[1],
        "palm_dz_m": palm[2], "side": 1.0 if plan["side"] == "paper" else -1.0}
    return [float(values[name]) for name in PLANNER_FEATURES]


@dataclass
class PlannerData:
    """A data set's maps as the planner reads them: one row per map."""
    objects: list[str]
    geometries: list[str]
    features: np.ndarray   # maps × PLANNER_FEATURES
    caught: np.ndarray     # maps × 10 × 15, True: in the target grasp
    labels: list           # each map's label cell (labels.py), or None
    paper_features: np.ndarray  # maps × the paper's five

    @staticmethod
    def load(data_dir: Path) -> "PlannerData":
        """The usable entries of data_dir (maps.npz and plans/), checked as
        load_prior_maps and read_plan check them."""
        data_dir = Path(data_dir)
        if not (data_dir / "maps.npz").exists():
            raise InputError(f"--data: {data_dir}: no maps.npz, expected a "
                             "data set (regrasp-drake dataset)")
        names, caught = load_prior_maps(data_dir / "maps.npz")
        features, geometries = [], []
        for name in names:
            plan = read_plan(data_dir / "plans" / f"{name}.json")
            obj = resolve_object(name=name.partition("@")[0])
            features.append(planner_features(obj, plan["plan"]))
            geometries.append(obj.geometry)
        features = np.array(features, float).reshape(-1, len(PLANNER_FEATURES))
        caught = np.asarray(caught, bool)
        return PlannerData(
            objects=list(names), geometries=geometries, features=features,
            caught=caught, labels=[label_cell(m) for m in caught],
            paper_features=features[:, :len(FEATURE_NAMES)])

    def share_in_target(self) -> dict:
        """How much of the maps succeeds: the mean share of cells, and how
        many maps lie in 10-90 % (where the cell matters)."""
        share = self.caught.reshape(len(self.caught), -1).mean(axis=1)
        return {"maps": len(share),
                "cells_in_target": round(float(share.mean()), 4),
                "maps_in_10_90": int(np.sum((share >= 0.1) & (share <= 0.9))),
                "maps_empty": int(np.sum(share == 0.0))}


# ---- the model -----------------------------------------------------------
def _cell_inputs() -> np.ndarray:
    """The 150 cells' two indices scaled to [0, 1], in the maps' row-major
    order."""
    i, j = np.meshgrid(np.arange(SHAPE[0]), np.arange(SHAPE[1]), indexing="ij")
    return np.stack([i.ravel() / (SHAPE[0] - 1), j.ravel() / (SHAPE[1] - 1)],
                    1)


class SuccessModel(torch.nn.Module):
    """P(the catch ends in the target grasp | features, cell): the mean of
    MEMBERS perceptrons, each over the standardized features and the cell's
    scaled indices (HIDDEN tanh, HIDDEN tanh, a logit), so that what is
    learned of one cell carries to its neighbours. Float32."""

    def __init__(self, n_features: int = len(PLANNER_FEATURES),
                 members: int = MEMBERS, hidden: int = HIDDEN):
        super().__init__()
        self.members = torch.nn.ModuleList(
            torch.nn.Sequential(
                torch.nn.Linear(n_features + 2, hidden), torch.nn.Tanh(),
                torch.nn.Linear(hidden, hidden), torch.nn.Tanh(),
                torch.nn.Linear(hidden, 1))
            for _ in range(members))
        self.register_buffer("mean", torch.zeros(n_features))
        self.register_buffer("std", torch.ones(n_features))

    def _inputs(self, features) -> torch.Tensor:
        """Every (map, cell) pair's inputs, map by map, cells row-major."""
        x = torch.as_tensor(np.atleast_2d(np.asarray(features, float)),
                            dtype=torch.float32)
        z = (x - self.mean) / self.std
        cells = torch.as_tensor(_cell_inputs(), dtype=torch.float32)
        return torch.cat([z.repeat_interleave(len(cells), 0),
                          cells.repeat(len(z), 1)], 1)

    def success_maps(self, features) -> np.ndarray:
        """maps × 10 × 15 predicted success probabilities."""
        with torch.no_grad():
            x = self._inputs(features)
            p = torch.stack([torch.sigmoid(m(x)[:, 0]) for m in self.members])
        return p.mean(0).numpy().astype(float).reshape(-1, *SHAPE)

    def fit(self, features: np.ndarray, caught: np.ndarray, *, seed: int = 0,
            epochs: int = EPOCHS) -> "SuccessModel":
        """Trains on every cell of the maps (maps × 10 × 15) by full-batch
        Adam on the cells' cross entropy; deterministic for a seed (one
        thread, as the callers set it)."""
        features = np.asarray(features, float)
        spread = features.std(axis=0)
        self.mean.copy_(torch.as_tensor(features.mean(axis=0)))
        self.std.copy_(torch.as_tensor(np.where(spread > 1e-12, spread, 1.0)))
        x = self._inputs(features)
        y = torch.as_tensor(np.asarray(caught, float).reshape(-1),
                            dtype=torch.float32)
        for k, member in enumerate(self.members):
            torch.manual_seed(seed * len(self.members) + k)
            for layer in member:
                if isinstance(layer, torch.nn.Linear):
                    layer.reset_parameters()
            optimizer = torch.optim.Adam(member.parameters(), lr=LEARNING_RATE,
                                         weight_decay=WEIGHT_DECAY)
            for _ in range(epochs):
                optimizer.zero_grad()
                loss = torch.nn.functional.binary_cross_entropy_with_logits(
                    member(x)[:, 0], y)
                loss.backward()
                optimizer.step()
        self.eval()
        return self

    # ---- its file ------------------------------------------------------
    def save(self, path: Path, metadata: dict) -> None:
        """One JSON file: the format, the metadata, every tensor as lists."""
        state = {k: v.tolist() for k, v in self.state_dict().items()}
        atomic_io.write_json(Path(path), {
            "format": _FORMAT, "features": list(PLANNER_FEATURES),
            "members": len(self.members),
            "hidden": self.members[0][0].out_features,
            "metadata": metadata, "state": state}, indent=None)

    @staticmethod
    def load(path: Path) -> tuple["SuccessModel", dict]:
        """The model and metadata `save` wrote; InputError naming the file
        and the field for anything else."""
        path = Path(path)
        data = load_tagged_json(path, "planner file", _FORMAT,
                                "regrasp-drake train --target KIND")
        if data.get("features") != list(PLANNER_FEATURES):
            raise field_error(f"{path}: features", data.get("features"),
                              f"{list(PLANNER_FEATURES)}")
        members, hidden = data.get("members"), data.get("hidden")
        for field, value in (("members", members), ("hidden", hidden)):
            if not isinstance(value, int) or not 1 <= value <= 64:
                raise field_error(f"{path}: {field}", value, "an integer 1-64")
        model = SuccessModel(members=members, hidden=hidden)
        state = data.get("state")
        if not isinstance(state, dict):
            raise field_error(f"{path}: state", type(state).__name__,
                              "the tensors by name")
        tensors = {}
        for name, expected in model.state_dict().items():
            try:
                tensor = torch.as_tensor(state[name], dtype=torch.float32)
            except (KeyError, TypeError, ValueError):
                raise field_error(f"{path}: state.{name}", "missing or not "
                                  "numbers", f"a tensor of shape "
                                  f"{tuple(expected.shape)}") from None
            if tuple(tensor.shape) != tuple(expected.shape):
                raise field_error(f"{path}: state.{name}", tuple(tensor.shape),
                                  f"shape {tuple(expected.shape)}")
            tensors[name] = tensor
        model.load_state_dict(tensors)
        model.eval()
        metadata = data.get("metadata")
        return model, metadata if isinstance(metadata, dict) else {}


def choose(success_map: np.ndarray, reach=None) -> tuple[int, int]:
    """The cell of highest predicted success among those the arm reaches
    (reach: per h_down column; None, all); ties to the lowest indices."""
    scores = np.array(success_map, float)
    if reach is not None:
        scores[:, ~np.asarray(reach, bool)] = -np.inf
    i, j = np.unravel_index(int(np.argmax(scores)), SHAPE)
    return int(i), int(j)


# ---- judging -------------------------------------------------------------
def splits(groups: list[str]) -> list[tuple[np.ndarray, np.ndarray]]:
    """(training, held-out) map indices, one split per group (sorted): the
    group's maps held out, every other map trained on."""
    groups = np.asarray(groups)
    return [(np.flatnonzero(groups != g), np.flatnonzero(groups == g))
            for g in sorted(set(groups.tolist()))]


def best_constant(caught: np.ndarray) -> tuple[int, int]:
    """The cell that succeeds on the most maps; ties to the lowest indices."""
    counts = np.asarray(caught, float).sum(axis=0)
    i, j = np.unravel_index(int(np.argmax(counts)), SHAPE)
    return int(i), int(j)


def _paper_network_cells(data: PlannerData, train, held_out, seed) -> list:
    """The paper's network trained on the training maps' labels (its
    split's early stopping on a tenth of them), its cells for held_out."""
    labelled = [k for k in train if data.labels[k] is not None]
    order = np.random.default_rng(seed).permutation(labelled)
    n_val = max(1, len(order) // 10)
    val, fit_on = sorted(order[:n_val]), sorted(order[n_val:]) or sorted(order)
    y = np.array([cell_parameters(data.labels[k]) if data.labels[k] else
                  (math.nan, math.nan) for k in range(len(data.labels))])
    x = data.paper_features
    torch.manual_seed(seed)
    model = CatchMlp()
    model.set_normalization(torch.as_tensor(x[fit_on]),
                            torch.as_tensor(y[fit_on]))

    def loss(rows):
        pred = (model(torch.as_tensor(x[rows])) - model.output_mean) / model.output_std
        true = (torch.as_tensor(y[rows]) - model.output_mean) / model.output_std
        return torch.mean((pred - true) ** 2)

    fit(model, lambda: loss(fit_on), lambda: -float(loss(val)),
        epochs=1000, learning_rate=0.01)
    with torch.no_grad():
        out = model(torch.as_tensor(x[held_out])).numpy()
    return [nearest_cell(*p) for p in out]


def judge(data: PlannerData, *, seed: int = 0, epochs: int = EPOCHS,
          progress=None, choices: dict | None = None) -> dict:
    """Each chooser's success rate over the held-out maps of the splits by
    geometry and by object (module docstring), and the number of splits.
    progress: called once a split is done (e.g. a tqdm bar's update);
    choices: a dict filled with the cell each chooser picked for each
    held-out map, choices[kind][map name][chooser] (the ceiling's: the
    held-out map's most robust cell, labels.py, or None when it has none)."""
    report = {}
    for kind, groups in (("by_geometry", data.geometries),
                         ("by_object", [o.partition("@")[0]
                                        for o in data.objects])):
        hits = {name: [] for name in CHOOSERS}
        folds = splits(groups)
        caught = data.caught
        for train, held_out in folds:
            model = SuccessModel().fit(data.features[train], caught[train],
                                       seed=seed, epochs=epochs)
            learned = model.success_maps(data.features[held_out])
            constant = best_constant(caught[train])
            paper = _paper_network_cells(data, train, held_out, seed)
            for k, m in enumerate(held_out):
                picked = {"learned": choose(learned[k]),
                          "paper_network": tuple(paper[k]),
                          "best_constant": constant}
                for name, cell in picked.items():
                    hits[name].append(caught[m][cell])
                hits["ceiling"].append(caught[m].any())
                if choices is not None:
                    choices.setdefault(kind, {})[data.objects[m]] = picked | {
                        "ceiling": data.labels[m]}
            if progress is not None:
                progress()
        report[kind] = {"splits": len(folds),
                        "maps": len(hits["learned"])} | {
            name: round(float(np.mean(h)), 4) for name, h in hits.items()}
    return report


def planner_file_name(kind: str, offset_mm: float) -> str:
    """The file of a target's planner: planner_flip+0.json, ..."""
    return f"planner_{kind}{offset_mm:+.0f}.json"


def train_planner(data_dir: Path, out: Path, *, seed: int = 0,
                  epochs: int = EPOCHS, maps: "PlannerData | None" = None,
                  progress=None) -> dict:
    """Judges the planner on data_dir's maps (`judge`), trains it on all of
    them, writes it to `out` with the report as its metadata, and returns
    the report. maps: data_dir's, when already loaded."""
    data = maps or PlannerData.load(data_dir)
    provenance = load_provenance(Path(data_dir) / "provenance.json")
    report = {"data": _shown(data_dir), "target": _target(provenance)}
    report |= data.share_in_target()
    report["best_cell_per_geometry_in_sample"] = per_geometry_bound(data)
    report |= judge(data, seed=seed, epochs=epochs, progress=progress)
    report["best_constant_cell"] = list(best_constant(data.caught))
    report["seed"], report["epochs"] = seed, epochs
    report["planner"] = winner(report)
    model = SuccessModel().fit(data.features, data.caught, seed=seed,
                               epochs=epochs)
    model.save(out, report)
    return report


def per_geometry_bound(data: PlannerData) -> float:
    """The success rate of each geometry's own best cell on its own maps:
    a bound, measured in sample, on any chooser that tells geometries
    apart but not the objects of one geometry."""
    geometries = np.asarray(data.geometries)
    hits = sum(int(data.caught[geometries == g][:, i, j].sum())
               for g in set(data.geometries)
               for i, j in [best_constant(data.caught[geometries == g])])
    return round(hits / len(geometries), 4)


def _shown(path: Path) -> str:
    """A path as a report shows it: from the checkout's top when inside."""
    path = Path(path).resolve()
    if REPO_DIR is not None and path.is_relative_to(REPO_DIR):
        return str(path.relative_to(REPO_DIR))
    return str(path)


def _target(provenance: dict) -> dict:
    """The target grasp a data set's scenario aims for."""
    target = target_of(load_scenario(text=provenance["scenario"]))
    return {"kind": target.kind, "offset_mm": target.offset_mm}


# ---- the planner the learning phase uses -------------------------------------
@dataclass
class Planner:
    """A chooser of a search's first cell, with what it needs: the model,
    or a constant cell (studies and tests: `winner` never ships one)."""
    # learned, best_constant or paper_network (library.CHOSEN_BY)
    name: str
    source: str                    # the planner file, or "none"
    model: SuccessModel | None = None
    cell: tuple | None = None

    def first_cell(self, obj: ObjectSpec, plan, network_cell, reach=None):
        """The cell a search starts from for `obj` caught under `plan` (a
        CatchPlan); network_cell: the paper network's."""
        if self.name == "learned":
            features = planner_features(obj, plan.as_dict())
            return choose(self.model.success_maps(features)[0], reach)
        if self.name == "best_constant":
            return self.cell
        return network_cell


def winner(report: dict) -> str:
    """The chooser a target's learning phase starts from: the learned
    planner when its figure by geometry beats both the paper's network's
    and the best constant cell's, else the paper's network. The best
    constant cell is a baseline, not a planner: where it leads by geometry
    on the training maps (flip 0 and +30 mm), starting from it made the
    Table 1 and held-out objects' first throws worse (docs/planner.md)."""
    rates = report["by_geometry"]
    if rates["learned"] > max(rates["best_constant"], rates["paper_network"]):
        return "learned"
    return "paper_network"


PAPER_NETWORK = Planner("paper_network", "none")


def load_planner(target, models_dir: Path | None = None) -> Planner:
    """The planner for a grasp target: the winner (`winner`) of its planner
    file in models_dir (default the shipped models), or the paper's network
    when there is none (the `any` target: its one cell that catches every
    training map is the paper network's finding, docs/maps-and-network.md)."""
    path = Path(models_dir or MODELS_DIR) / planner_file_name(
        target.kind, target.offset_mm)
    if target.kind == "any" or not path.exists():
        return PAPER_NETWORK
    model, report = SuccessModel.load(path)
    try:
        name = winner(report)
    except (KeyError, TypeError):
        raise InputError(f"{path}: metadata: no by_geometry rates, expected "
                         "the report `regrasp-drake train --target` writes"
                         ) from None
    return Planner(name, str(path), model=model) if name == "learned" \
        else PAPER_NETWORK
