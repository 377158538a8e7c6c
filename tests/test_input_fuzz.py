"""A seeded mutation fuzzer over the files a user hands to the commands:
object files, scenarios and regrasp libraries, the data set's files
(samples.csv, an entry's plan and cells, provenance.json, maps.npz), the
flight predictor and the network's weights, each mutated from a shipped
valid file (types, magnitudes, shapes, NaN/inf, deletions, duplications,
nesting, aliases, encodings, number notations, bytes of the binary files).
Every mutant is either accepted or refused with one line (InputError, exit 2
on the command line): never a traceback, an abort, a hang, or a changed
input file.

The bulk runs the loaders in this process; a few mutants run through the
command line, with commands that refuse before any simulation. Set
REGRASP_FUZZ_SEED to explore other mutants than the default seed's.
"""

import copy
import csv
import dataclasses as dc
import io
import json
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
import unittest
import warnings
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import torch
import yaml

from regrasp_drake.errors import InputError
from regrasp_drake.grid import read_rows
from regrasp_drake.input_files import dump_yaml, parse_yaml
from regrasp_drake.learning.dataset_files import (
    load_provenance,
    load_samples,
    read_plan,
)
from regrasp_drake.learning.flight_predictor import FlightPredictor, dataset_flights
from regrasp_drake.learning.library import load_library
from regrasp_drake.learning.search import load_prior_maps
from regrasp_drake.paths import MODELS_DIR
from regrasp_drake.station.mlp_system import load_weights
from regrasp_drake.station.scenario import Scenario, load_scenario, scenario_yaml
from regrasp_drake.world.objects import CATALOGUE_PATH, load_catalogue, load_object_file

REPO = Path(__file__).parents[1]
DATASET = MODELS_DIR / "dataset"
SEED = int(os.environ.get("REGRASP_FUZZ_SEED", "30"))
MUTANTS_PER_FORMAT = 150        # of the object, scenario and library files
MUTANTS_PER_MODEL_FORMAT = 50   # of the data set's, predictor's, weights'
# A loader that takes longer than this on a file of a few kB hangs: CPU
# time of this process (ITIMER_PROF), so that a loaded machine does not
# count as a hang.
TIME_LIMIT_S = 5.0


def _object_seed() -> dict:
    """Two catalogue geometries (one of several pieces) and their first
    objects: a small valid object file."""
    catalogue = yaml.safe_load(CATALOGUE_PATH.read_text())
    kept = ("hammer", "spool")
    return {"geometries": {k: catalogue["geometries"][k] for k in kept},
            "objects": [o for o in catalogue["objects"]
                        if o["geometry"] in kept][:3]}


def _scenario_seed() -> dict:
    # Tagged: the directives' rotations (!Rpy).
    return parse_yaml(scenario_yaml(Scenario()), tags=True)


def _library_seed() -> dict:
    path = REPO / "models" / "results" / "library_table1.yaml"
    return yaml.safe_load(path.read_text())


ENTRY = "hammer-d100-1"  # a data set entry with a plan and a map


def _samples_seed() -> list:
    with open(DATASET / "samples.csv", newline="") as f:
        return list(csv.DictReader(f))[:8]


def _plan_seed() -> dict:
    return json.loads((DATASET / "plans" / f"{ENTRY}.json").read_text())


def _cells_seed() -> list:
    lines = (DATASET / "cells" / f"{ENTRY}.jsonl").read_text().splitlines()
    return [json.loads(line) for line in lines[:12]]


def _provenance_seed() -> dict:
    return json.loads((DATASET / "provenance.json").read_text())


def _maps_seed() -> dict:
    with np.load(DATASET / "maps.npz") as data:
        return {k: data[k][:6] if k in ("objects", "caught", "features")
                else data[k] for k in data.files}


def _flight_model_seed() -> dict:
    return json.loads((MODELS_DIR / "flight_predictor.json").read_text())


def _weights_seed() -> dict:
    return torch.load(MODELS_DIR / "catch_mlp.pt", weights_only=True)


# ---- mutations -------------------------------------------------------------
def _places(tree, path=()):
    """Every (container path, key or index) of the tree."""
    items = (tree.items() if isinstance(tree, dict)
             else enumerate(tree) if isinstance(tree, list) else ())
    for key, value in items:
        yield path + (key,)
        yield from _places(value, path + (key,))


def _get(tree, path):
    for key in path:
        tree = tree[key]
    return tree


def _odd_array(rng: random.Random, old):
    """An array (numpy) or tensor (torch) of another shape, type or
    magnitude than `old`, or non-finite."""
    if isinstance(old, torch.Tensor):
        floats = old.to(torch.float64)
        return rng.choice([
            lambda: old.reshape(-1), lambda: old[:0], lambda: old[..., :1],
            lambda: torch.cat([old, old]), lambda: old.t(),
            lambda: floats * float("nan"), lambda: floats * 1e300,
            lambda: old.to(torch.float32) * 1e38, lambda: old.to(torch.int64),
            lambda: old.to(torch.float16), lambda: old.to(torch.bool),
            lambda: old.to(torch.complex64), lambda: old.numpy(),
            lambda: torch.zeros(1000, 1000), lambda: old.tolist(),
        ])()
    floats = (old.astype(float) if old.dtype.kind in "biuf"
              else np.zeros(old.shape))
    return rng.choice([
        lambda: old.reshape(-1), lambda: old[:0], lambda: old[..., :1],
        lambda: np.concatenate([old, old]), lambda: old.T,
        lambda: np.full(old.shape, np.nan), lambda: floats * 1e300,
        lambda: old.astype(object), lambda: old.astype(str),
        lambda: floats, lambda: np.zeros((600, 10, 15), bool),
        lambda: np.array(3.0), lambda: old.tolist(),
    ])()


def _odd_value(rng: random.Random, old):
    """A value of another type or magnitude than `old`, or non-finite."""
    if isinstance(old, (np.ndarray, torch.Tensor)) and rng.random() < 0.7:
        return _odd_array(rng, old)
    number = old if isinstance(old, (int, float)) and not isinstance(
        old, bool) else 1.0
    return rng.choice([
        "text", "", "x" * 5000, None, True, [], {}, [1, 2], {"a": 1},
        float("nan"), float("inf"), -float("inf"), 1e308, -1e308, 1e-308,
        10 ** 30, -(10 ** 30), 0, -1, number * 10 ** rng.randint(2, 12),
        number * 10 ** -rng.randint(2, 12), -number, number + 1e-9,
        "1e5", "2001-01-01", b"\x00\xff",
    ])


def _mutate_tree(rng: random.Random, tree) -> tuple[str, object]:
    """One structural mutation of a copy of the tree: (its name, the tree)."""
    tree = copy.deepcopy(tree)
    places = list(_places(tree))
    path = rng.choice(places)
    parent, key = _get(tree, path[:-1]), path[-1]
    kind = rng.choice(["value", "value", "value", "delete", "duplicate",
                       "rename", "nest", "share", "swap"])
    if kind == "value":
        parent[key] = _odd_value(rng, parent[key])
    elif kind == "delete":
        del parent[key]
    elif kind == "duplicate":
        if isinstance(parent, list):
            parent.insert(key, copy.deepcopy(parent[key]))
        else:
            parent[f"{key}_copy"] = copy.deepcopy(parent[key])
    elif kind == "rename":
        if isinstance(parent, dict):
            parent[rng.choice(["x" * 300, 7, "Name", str(key) + "s"])] = \
                parent.pop(key)
        else:
            parent.append(parent[key])
    elif kind == "nest":
        value = parent[key]
        for _ in range(rng.choice([1, 3, 20, 40])):
            value = [value]
        parent[key] = value
    elif kind == "share":  # yaml.safe_dump writes it as an anchor and alias
        # Not an enclosing node: no cycle (that one is a text mutation).
        other = rng.choice([p for p in places if p != path[:len(p)]] or [path])
        parent[key] = _get(tree, other)
    else:  # swap two values
        other_path = rng.choice(places)
        other_parent = _get(tree, other_path[:-1])
        parent[key], other_parent[other_path[-1]] = (
            other_parent[other_path[-1]], parent[key])
    return kind, tree


_UNSERIALIZABLE = "{unserializable: [\n"  # a syntax error, fine as a mutant


def _dump(tree) -> str:
    try:
        return yaml.safe_dump(tree, sort_keys=False)
    except (yaml.YAMLError, RecursionError, ValueError):
        return _UNSERIALIZABLE


def _dump_tagged(tree) -> str:
    """_dump, Tagged mappings with their tag."""
    try:
        return dump_yaml(tree)
    except (yaml.YAMLError, RecursionError, ValueError):
        return _UNSERIALIZABLE


def _dump_json(tree) -> str:
    try:  # NaN and Infinity as Python writes them
        return json.dumps(tree, indent=1)
    except (TypeError, ValueError, RecursionError):
        return _UNSERIALIZABLE


def _dump_json_lines(rows) -> str:
    return "".join(_dump_json(row).replace("\n", "") + "\n" for row in rows)


def _dump_csv(rows) -> str:
    """Rows (mappings; anything else is written as one cell) as CSV, the
    header the union of their keys."""
    header = list(dict.fromkeys(k for row in rows if isinstance(row, dict)
                                for k in row))
    f = io.StringIO()
    writer = csv.writer(f)
    writer.writerow(header)
    for row in rows:
        writer.writerow([row.get(k, "") for k in header]
                        if isinstance(row, dict) else [row])
    return f.getvalue()


def _dump_npz(tree) -> bytes:
    f = io.BytesIO()
    try:
        np.savez(f, **tree)
    except (TypeError, ValueError):
        return b"PK\x03\x04 not an archive"
    return f.getvalue()


def _dump_torch(tree) -> bytes:
    f = io.BytesIO()
    try:
        torch.save(tree, f)
    except (TypeError, ValueError, RuntimeError, RecursionError):
        return b"PK\x03\x04 not an archive"
    return f.getvalue()


def _mutate_bytes(rng: random.Random, data: bytes) -> tuple[str, bytes]:
    """One mutation of a binary file's bytes: (its name, the bytes)."""
    kind = rng.choice(["truncate", "flip", "insert", "random bytes", "empty",
                       "append", "zeros"])
    i = rng.randrange(len(data))
    if kind == "truncate":
        return kind, data[:i]
    if kind == "flip":
        data = bytearray(data)
        for _ in range(rng.choice([1, 4, 64])):
            data[rng.randrange(len(data))] ^= 1 << rng.randrange(8)
        return kind, bytes(data)
    if kind == "insert":
        return kind, data[:i] + rng.randbytes(rng.randint(1, 64)) + data[i:]
    if kind == "random bytes":
        return kind, rng.randbytes(rng.randint(1, 4000))
    if kind == "empty":
        return kind, b""
    if kind == "append":
        return kind, data + rng.randbytes(rng.randint(1, 400))
    return kind, data[:i] + bytes(rng.randint(1, 4000)) + data[i:]


_BOMB = "\n".join(
    ["bomb0: &b0 [x, x, x, x, x, x, x, x, x, x]"]
    + [f"bomb{i}: &b{i} [" + ", ".join([f"*b{i - 1}"] * 10) + "]"
       for i in range(1, 9)]) + "\n"


def _mutate_text(rng: random.Random, text: str) -> tuple[str, bytes]:
    """One mutation of the file's text or bytes: (its name, the bytes)."""
    lines = text.splitlines(keepends=True)
    kind = rng.choice(["duplicate line", "delete line", "truncate", "bomb",
                       "bomb under key", "self alias", "utf-16", "latin-1",
                       "nul", "random bytes", "bom", "deep", "notation",
                       "nan text", "huge number"])
    i = rng.randrange(len(lines))
    data = None
    if kind == "duplicate line":
        lines.insert(i, lines[i])
    elif kind == "delete line":
        del lines[i]
    elif kind == "truncate":
        text = text[:rng.randrange(len(text))]
        lines = [text]
    elif kind == "bomb":
        lines.insert(0, _BOMB)
    elif kind == "bomb under key":  # the bomb where a value is expected
        lines = [_BOMB.replace("bomb8", "x"), *lines]
        lines = [line.replace(": 0.", ": *b8 #", 1) for line in lines]
    elif kind == "self alias":
        lines.insert(0, "loop: &loop [1, *loop]\n")
    elif kind == "utf-16":
        data = text.encode("utf-16")
    elif kind == "latin-1":
        data = ("# Gewicht: 2 kg, Dichte 200 kg/m³\n" + text).encode("latin-1")
    elif kind == "nul":
        lines.insert(i, "\0\n")
    elif kind == "random bytes":
        data = bytes(rng.randrange(256) for _ in range(rng.randint(1, 400)))
    elif kind == "bom":
        data = b"\xef\xbb\xbf" + text.encode()
    elif kind == "deep":
        lines.insert(0, "deep: " + "[" * 5000 + "]" * 5000 + "\n")
    elif kind == "notation":  # numbers as people write them: must load
        lines = [line.replace("100000.0", "1e5").replace("0.001", "1.0e-3")
                 for line in lines]
    elif kind == "nan text":
        lines[i] = lines[i].replace("0.", ".nan #", 1)
    else:
        lines[i] = lines[i].replace("0.", "1" * 400 + ".", 1)
    return kind, data if data is not None else "".join(lines).encode()


def mutants(fmt: "Format", count: int, rng: random.Random):
    """`count` mutants (name, bytes) of the format's seed: half structural,
    half textual (or of the bytes, for a binary format), a few twice
    mutated."""
    seed_tree = fmt.seed()
    base = fmt.dump(seed_tree)
    for n in range(count):
        if n % 2:
            name, data = (_mutate_bytes(rng, base) if fmt.binary
                          else _mutate_text(rng, base))
        else:
            name, tree = _mutate_tree(rng, seed_tree)
            if n % 10 == 4:
                second, tree = _mutate_tree(rng, tree)
                name = f"{name}+{second}"
            data = fmt.dump(tree)
            name = f"tree {name}"
        yield name, data if isinstance(data, bytes) else data.encode()


# ---- the oracle ------------------------------------------------------------
class _Hang(Exception):
    pass


def _alarm(signum, frame):
    raise _Hang


def _outcome(load, path: Path) -> tuple[str | None, bool]:
    """(None when load(path) accepts the file or refuses it in one line,
    else what went wrong; whether it accepted the file)."""
    before = path.read_bytes()
    old = signal.signal(signal.SIGPROF, _alarm)
    signal.setitimer(signal.ITIMER_PROF, TIME_LIMIT_S)
    start = time.process_time()
    accepted, warned = False, []
    try:
        with warnings.catch_warnings(record=True) as warned:
            warnings.simplefilter("always")
            load(path)
        problem, accepted = None, True
    except InputError as e:
        message = str(e)
        problem = (None if "\n" not in message and len(message) < 1000
                   else f"refusal not one short line: {message[:300]!r}")
    except _Hang:
        problem = f"no answer within {TIME_LIMIT_S} s of CPU time"
    except BaseException as e:  # noqa: BLE001 - anything else is the bug
        problem = f"{type(e).__name__}: {str(e)[:300]}"
    finally:
        signal.setitimer(signal.ITIMER_PROF, 0)
        signal.signal(signal.SIGPROF, old)
    if problem is None and warned:  # a line more on stderr
        problem = f"a warning: {warned[0].message}"
    if problem is None and time.process_time() - start > TIME_LIMIT_S:
        problem = "took longer than the time limit"
    if path.read_bytes() != before:
        problem = "the input file was changed"
    return problem, accepted


def _load_plan(path: Path) -> None:
    """An entry's plan, as `dataset` (resuming) and `train-flight` read it."""
    read_plan(path)
    dataset_flights(path.parents[1])


def _load_flight_model(path: Path) -> None:
    """The predictor, and its prediction for an object (which `learn
    --first-throw` then plans a catch from): finite."""
    state = FlightPredictor.load(path).predict_state(_OBJECT, _SCENARIO)
    if not np.all(np.isfinite(state)):
        raise AssertionError(f"accepted, but predicts {state}")


_OBJECT = load_catalogue()["table1-row2"]
_SCENARIO = load_scenario()


@dc.dataclass(frozen=True)
class Format:
    seed: object              # () -> the parsed shipped file
    load: object              # path -> anything; raises InputError
    dump: object = _dump      # parsed -> text or bytes
    name: str = "file.yaml"   # the file's path in its (data set) directory
    binary: bool = False      # bytes mutated instead of text
    count: int = MUTANTS_PER_FORMAT
    # Most mutants are refused (a format whose every field is checked).
    strict: bool = True


_MODEL = dict(count=MUTANTS_PER_MODEL_FORMAT)
FORMATS = {
    "object file": Format(_object_seed, load_object_file),
    "scenario": Format(_scenario_seed, load_scenario, _dump_tagged),
    "library": Format(_library_seed, load_library),
    "samples": Format(_samples_seed, lambda path: load_samples(path.parent),
                      _dump_csv, "samples.csv", **_MODEL),
    # (Its record of the plan is for the reader: no command reads it.)
    "plan": Format(_plan_seed, _load_plan, _dump_json,
                   f"plans/{ENTRY}.json", strict=False, **_MODEL),
    "cells": Format(_cells_seed, read_rows, _dump_json_lines,
                    f"cells/{ENTRY}.jsonl", strict=False, **_MODEL),
    "provenance": Format(_provenance_seed, load_provenance, _dump_json,
                         "provenance.json", strict=False, **_MODEL),
    "maps": Format(_maps_seed, lambda path: load_prior_maps(
        path, with_features=True), _dump_npz, "maps.npz", binary=True,
        **_MODEL),
    # (Its list of the objects it was fitted on is for the reader.)
    "flight model": Format(_flight_model_seed, _load_flight_model, _dump_json,
                           "flight_predictor.json", strict=False, **_MODEL),
    # (Its metadata is free: what training recorded.)
    "weights": Format(_weights_seed, load_weights, _dump_torch, "catch_mlp.pt",
                      binary=True, strict=False, **_MODEL),
}


def _write_mutant(directory: Path, fmt: Format, data: bytes) -> Path:
    """The mutant at fmt.name in a new directory under `directory`."""
    path = Path(tempfile.mkdtemp(dir=directory)) / fmt.name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(data)
    return path


class LoaderFuzzTest(unittest.TestCase):
    """Format.count mutants of each format, loaded in process."""

    def test_every_mutant_accepted_or_refused_in_one_line(self):
        rng = random.Random(SEED)
        failures, counts = [], {}
        with tempfile.TemporaryDirectory() as d:
            for key, fmt in FORMATS.items():
                accepted = 0
                for n, (name, data) in enumerate(mutants(fmt, fmt.count, rng)):
                    path = _write_mutant(Path(d), fmt, data)
                    problem, ok = _outcome(fmt.load, path)
                    if problem is not None:
                        failures.append(f"{key} #{n} ({name}): {problem}")
                    accepted += ok
                counts[key] = accepted
        self.assertEqual(failures, [], f"seed {SEED}")
        self.assertGreaterEqual(sum(f.count for f in FORMATS.values()), 800)
        # The fuzzer reaches past the first check: some mutants stay valid,
        # most are refused (of a format whose every field is checked).
        for key, accepted in counts.items():
            with self.subTest(key):
                self.assertGreater(accepted, 0)
                most = FORMATS[key].count // (2 if FORMATS[key].strict else 1)
                self.assertLess(accepted, most)

    def test_numbers_in_every_notation_read_alike(self):
        with tempfile.TemporaryDirectory() as d:
            path = Path(d) / "s.yaml"
            for text in ("1e5", "1.0e5", "100000", "1E+5", "100_000"):
                path.write_text(f"contact:\n  point_stiffness_N_per_m: {text}\n")
                with self.subTest(text):
                    self.assertEqual(load_scenario(path).contact
                                     .point_stiffness_N_per_m, 1e5)


def _run(*args):
    return subprocess.run([sys.executable, "-m", "regrasp_drake.cli", *args],
                          capture_output=True, text=True, timeout=60)


class CommandLineFuzzTest(unittest.TestCase):
    """A few mutants of each format through the command line, with commands
    that refuse before any simulation whatever the mutant holds: `objects`
    (never simulates); `throw` and `learn` given an object file that is
    refused; `train` and `train-flight` given a data set without maps.npz
    or with a sample of no map, or with one plan (too few flights); `grid`
    with too many workers; `table1` given an object not in the catalogue
    (refused after the network and the predictor are read)."""

    def test_mutants_exit_0_or_2_with_one_line(self):
        rng = random.Random(SEED + 1)
        with tempfile.TemporaryDirectory() as d:
            d = Path(d)
            no_object = d / "no_object.yaml"
            no_object.write_text("geometries: {}\nobjects: []\n")
            runs = []
            for key, fmt in FORMATS.items():
                # One of each data set's, predictor's and weights' file, two
                # of a map's cells: most of their commands import torch (some
                # 3 s a run).
                count = (6 if fmt.count == MUTANTS_PER_FORMAT
                         else 2 if key == "cells" else 1)
                for n, (name, data) in enumerate(mutants(fmt, count, rng)):
                    path = _write_mutant(d, fmt, data)
                    args = self._command(key, path, no_object, d)
                    runs.append((f"{key} #{n} ({name})", path, data,
                                 [str(a) for a in args]))
            with ThreadPoolExecutor(2) as pool:
                results = list(pool.map(lambda run: _run(*run[3]), runs))
            for (what, path, data, args), result in zip(runs, results):
                with self.subTest(what):
                    self.assertIn(result.returncode, (0, 2), result.stderr)
                    self.assertNotIn("Traceback", result.stderr)
                    if result.returncode == 2:
                        self.assertEqual(
                            len(result.stderr.strip().splitlines()), 1,
                            result.stderr)
                    self.assertEqual(path.read_bytes(), data)
        self.assertGreaterEqual(len(runs), 26)

    @staticmethod
    def _command(key: str, path: Path, no_object: Path, d: Path) -> list:
        """A command that reads the mutant at path, then refuses."""
        data = path.parents[1] if key == "plan" else path.parent
        if key == "maps":  # a sample whose entry has no map
            rows = _samples_seed()[:1]
            rows[0]["object"] = "none-such"
            (data / "samples.csv").write_text(_dump_csv(rows))
        if key == "provenance":  # no maps.npz
            (data / "samples.csv").write_text(_dump_csv(_samples_seed()))
        if key == "cells":
            (path.parent / f"{path.name}.plan.json").write_text("{}\n")
        table1 = ["table1", "--objects", "none-such", "--no-maps",
                  "--library", d / "library.yaml"]
        return {
            "object file": ["objects", "--object-file", path],
            "scenario": ["throw", "--object-file", no_object, "--scenario",
                         path],
            "library": ["learn", "--object-file", no_object, "--library",
                        path],
            "samples": ["train", "--data", data, "--out-dir", d],
            "maps": ["train", "--data", data, "--out-dir", d],
            "provenance": ["train", "--data", data, "--out-dir", d],
            "plan": ["train-flight", "--data", data, "--out-dir", d],
            "cells": ["grid", "--object", "table1-row2", "--out", path,
                      "--workers", "100000"],
            "flight model": [*table1, "--first-throw", "--flight-model",
                             path],
            "weights": [*table1, "--weights", path],
        }[key]


if __name__ == "__main__":
    unittest.main()
