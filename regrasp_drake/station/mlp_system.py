"""The network that picks a catch's parameters (paper §V, Fig. 3), its weights
file, and the Drake system that runs it.

The network is a two-layer perceptron, 5 inputs → 13 tanh neurons → 2 linear
outputs, as Matlab's `newff` built them (its default hidden transfer function
`tansig` is tanh, its output `purelin` is linear). Inputs and outputs are
normalized by means and standard deviations kept in the module (and in its
weights file).

Threads: torch uses every core by default, and torch in a forked worker hangs
if its parent used more than one thread. Callers that run episodes in worker
processes call `torch.set_num_threads(1)` before any forward pass; this module
does not change torch's global settings.
"""

import copy
import io
import json
import math
import os
from dataclasses import dataclass

import numpy as np
import torch
from pydrake.systems.framework import LeafSystem

from regrasp_drake import atomic_io
from regrasp_drake.errors import InputError, field_error
from regrasp_drake.input_files import read_bytes
from regrasp_drake.parameter_space import cell_parameters, nearest_cell

# The network's inputs, in order (paper §V): the object's vertical velocity at
# the catch point (m/s), the height h_cm and radius r_cm (m) of its centre of
# mass in the object frame, its density d_obj (kg/m³), and v_conv, its number
# of convex vertices.
FEATURE_NAMES = ("v_catch", "h_cm", "r_cm", "d_obj", "v_conv")
# The network's outputs, in order: the catch height and the height the hand
# moves down while catching (m).
PARAMETER_NAMES = ("h_catch", "h_down")
NUM_HIDDEN = 13

_FORMAT = "regrasp_drake.CatchMlp"
_FORMAT_VERSION = 1
# Bounds of a weights file's values: the shipped network's largest is 248
# (a feature's mean); the scales it divides by are at least 0.1.
MAX_WEIGHT = 1e4
MIN_STD = 1e-9


class CatchMlp(torch.nn.Module):
    """features (5) → normalize → Linear(5, 13) → tanh → Linear(13, 2) →
    unnormalize → (h_catch, h_down) in m. Float64 throughout."""

    def __init__(self):
        super().__init__()
        n_in, n_out = len(FEATURE_NAMES), len(PARAMETER_NAMES)
        self.hidden = torch.nn.Linear(n_in, NUM_HIDDEN, dtype=torch.float64)
        self.output = torch.nn.Linear(NUM_HIDDEN, n_out, dtype=torch.float64)
        self.register_buffer("input_mean", torch.zeros(n_in, dtype=torch.float64))
        self.register_buffer("input_std", torch.ones(n_in, dtype=torch.float64))
        self.register_buffer("output_mean", torch.zeros(n_out, dtype=torch.float64))
        self.register_buffer("output_std", torch.ones(n_out, dtype=torch.float64))

    def set_normalization(self, features: torch.Tensor, parameters: torch.Tensor):
        """Sets the normalization from training data: features (N×5) and
        parameters (N×2). A column with no spread keeps a std of 1."""
        for mean, std, data in (
            (self.input_mean, self.input_std, features),
            (self.output_mean, self.output_std, parameters),
        ):
            data = torch.as_tensor(data, dtype=torch.float64)
            spread = data.std(dim=0) if data.shape[0] > 1 else torch.zeros_like(std)
            mean.copy_(data.mean(dim=0))
            std.copy_(torch.where(spread > 1e-12, spread, torch.ones_like(spread)))

    def forward(self, features: torch.Tensor) -> torch.Tensor:
        z = (features - self.input_mean) / self.input_std
        y = self.output(torch.tanh(self.hidden(z)))
        return y * self.output_std + self.output_mean


def save_weights(path, model: CatchMlp, metadata: dict):
    """Writes the model's tensors and JSON-able `metadata` to one file at path
    (a plain dict of tensors, strings and numbers, written by torch.save)."""
    if not isinstance(metadata, dict):
        raise field_error("metadata", type(metadata).__name__, "a JSON-able dict")
    try:
        json.dumps(metadata)
    except (TypeError, ValueError) as e:
        raise field_error("metadata", metadata, f"a JSON-able dict ({e})") from None
    state = {
        k: v.detach().to(torch.float64).clone() for k, v in model.state_dict().items()
    }
    # Atomically: a train killed mid-write leaves the old weights whole.
    with atomic_io.replace(path, "wb") as f:
        torch.save(
            {
                "format": _FORMAT,
                "version": _FORMAT_VERSION,
                "state_dict": state,
                "metadata": metadata,
            },
            f,
        )


def load_weights(path) -> tuple[CatchMlp, dict]:
    """Returns the model and metadata stored at path by save_weights.

    Loads with `weights_only=True`, so no code is ever unpickled. Raises
    InputError naming the file and what is wrong with it, on one line.
    """
    path = os.fspath(path)
    if not os.path.exists(path):
        raise InputError(f"{path}: no such weights file")
    # A regular file of at most input_files.MAX_FILE_BYTES (not a device).
    raw = read_bytes(path, "weights file")
    try:
        data = torch.load(io.BytesIO(raw), map_location="cpu", weights_only=True)
    except Exception as e:  # torch raises many kinds for a bad file.
        reason = _load_failure(e)
        raise InputError(
            f"{path}: not a weights file loadable with weights_only "
            f"({type(e).__name__}: {reason})"
        ) from None
    if not isinstance(data, dict) or data.get("format") != _FORMAT:
        raise InputError(f"{path}: not a {_FORMAT} weights file (format tag missing)")
    if data.get("version") != _FORMAT_VERSION:
        raise field_error(f"{path}: version", data.get("version"), str(_FORMAT_VERSION))
    state, metadata = data.get("state_dict"), data.get("metadata")
    if not isinstance(state, dict):
        raise InputError(f"{path}: state_dict missing")
    if not isinstance(metadata, dict):
        raise InputError(f"{path}: metadata missing")
    model = CatchMlp()
    for name, expected in model.state_dict().items():
        tensor = state.get(name)
        if not isinstance(tensor, torch.Tensor):
            raise InputError(f"{path}: tensor {name} missing")
        if tuple(tensor.shape) != tuple(expected.shape):
            raise field_error(
                f"{path}: tensor {name} shape",
                tuple(tensor.shape),
                str(tuple(expected.shape)),
            )
        if not torch.isfinite(tensor).all():
            raise InputError(f"{path}: tensor {name} holds non-finite values")
        largest = float(tensor.abs().max()) if tensor.numel() else 0.0
        if largest > MAX_WEIGHT:
            raise field_error(f"{path}: tensor {name} magnitude", largest,
                              f"at most {MAX_WEIGHT:g}")
        if name.endswith("_std") and tensor.numel() and float(
                tensor.min()) < MIN_STD:
            raise field_error(f"{path}: tensor {name} minimum",
                              float(tensor.min()), f"at least {MIN_STD:g} "
                              "(a scale the network divides by)")
    unknown = sorted(set(state) - set(model.state_dict()))
    if unknown:
        raise InputError(f"{path}: unknown tensors {unknown}")
    model.load_state_dict(state)
    model.eval()
    return model, metadata


@dataclass(frozen=True)
class ParameterSpace:
    """Bounds (m) of the catch parameters (paper §V.A)."""

    h_catch_min: float = 0.0
    h_catch_max: float = 0.40
    h_down_min: float = -0.14
    h_down_max: float = 0.0

    def clamp(self, h_catch: float, h_down: float) -> tuple[float, float]:
        """Returns (h_catch, h_down) clamped into the bounds (m)."""
        if not (math.isfinite(h_catch) and math.isfinite(h_down)):
            raise field_error("catch_parameters", (h_catch, h_down), "finite numbers")
        return (
            min(max(h_catch, self.h_catch_min), self.h_catch_max),
            min(max(h_down, self.h_down_min), self.h_down_max),
        )


class MlpSystem(LeafSystem):
    """Runs a CatchMlp once per episode.

    Input port `features`: (v_catch, h_cm, r_cm, d_obj, v_conv).
    Output port `catch_parameters`: (h_catch, h_down) in m, clamped to the
    parameter space; with `grid_cells`, the values of the grid cell nearest
    them (parameter_space.nearest_cell), the cell the learning phase's
    search starts from. The features are constant during an episode, so
    the network runs only in an initialization event (Simulator.Initialize)
    and its result is held as discrete state; before initialization the
    output is NaN.
    """

    def __init__(
        self, model: CatchMlp, parameter_space: ParameterSpace = ParameterSpace(),
        grid_cells: bool = False,
    ):
        LeafSystem.__init__(self)
        # A private float64 copy in eval mode: the caller may go on training.
        self._model = copy.deepcopy(model).to(torch.float64).eval()
        self._space = parameter_space
        self._grid_cells = grid_cells
        self._features_port = self.DeclareVectorInputPort(
            "features", len(FEATURE_NAMES)
        )
        state = self.DeclareDiscreteState(np.full(len(PARAMETER_NAMES), np.nan))
        self.DeclareInitializationDiscreteUpdateEvent(update=self._initialize)
        self.DeclareStateOutputPort("catch_parameters", state)

    def parameters_for(self, features) -> tuple[float, float]:
        """Returns the clamped (h_catch, h_down) (m) for one feature vector
        (with grid_cells, its nearest cell's)."""
        with torch.no_grad():
            x = torch.as_tensor(np.asarray(features, dtype=np.float64))
            h_catch, h_down = self._model(x).tolist()
        clamped = self._space.clamp(h_catch, h_down)
        if self._grid_cells:
            return cell_parameters(nearest_cell(*clamped))
        return clamped

    def _initialize(self, context, discrete_state):
        discrete_state.set_value(
            0, self.parameters_for(self._features_port.Eval(context))
        )


def _load_failure(e: Exception) -> str:
    """What torch.load found wrong, in a few words: the unpickler's own
    reason when it gives one (not torch's advice to load without weights_only,
    which would run code from the file), else the first sentence."""
    advice = ("Weights only load failed", "weights_only", "trusted source",
              "Check the documentation", "Please file an issue",
              "Alternatively", "two options")
    marker = "WeightsUnpickler error:"
    text = str(e).replace("\x1b[1m", "").replace("\x1b[0m", "")
    if marker in text:
        text = text.split(marker, 1)[1]
    for line in text.splitlines():
        line = " ".join(line.split())
        if line and not any(a in line for a in advice):
            return line.split(". ", 1)[0].rstrip(".")[:160]
    return " ".join(text.split()).split(". ", 1)[0].rstrip(".")[:160]
