"""A seeded mutation fuzzer over the files a user hands to the commands:
object files, scenarios and regrasp libraries, each mutated from a shipped
valid file (types, magnitudes, NaN/inf, deletions, duplications, nesting,
aliases, encodings, number notations). Every mutant is either accepted or
refused with one line (InputError, exit 2 on the command line): never a
traceback, an abort, a hang, or a changed input file.

The bulk runs the loaders in this process; a few mutants run through the
command line, with commands that refuse before any simulation. Set
REGRASP_FUZZ_SEED to explore other mutants than the default seed's.
"""

import copy
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

import yaml
from pydrake.common.yaml import yaml_dump_typed

from regrasp_drake.errors import InputError
from regrasp_drake.learning.library import load_library
from regrasp_drake.station.scenario import Scenario, load_scenario
from regrasp_drake.world.objects import CATALOGUE_PATH, load_object_file

REPO = Path(__file__).parents[1]
SEED = int(os.environ.get("REGRASP_FUZZ_SEED", "30"))
MUTANTS_PER_FORMAT = 150
# A loader that takes longer than this on a file of a few kB hangs.
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
    return yaml.safe_load(yaml_dump_typed(Scenario(), schema=Scenario))


def _library_seed() -> dict:
    path = REPO / "models" / "results" / "library_table1.yaml"
    return yaml.safe_load(path.read_text())


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


def _odd_value(rng: random.Random, old):
    """A value of another type or magnitude than `old`, or non-finite."""
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


def _dump(tree) -> str:
    try:
        return yaml.safe_dump(tree, sort_keys=False)
    except (yaml.YAMLError, RecursionError, ValueError):
        return "{unserializable: [\n"  # a syntax error, fine as a mutant


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


def mutants(seed_tree, count: int, rng: random.Random):
    """`count` mutants (name, bytes) of the tree: half structural, half
    textual, a few twice mutated."""
    base = _dump(seed_tree)
    for n in range(count):
        if n % 2:
            name, data = _mutate_text(rng, base)
        else:
            name, tree = _mutate_tree(rng, seed_tree)
            if n % 10 == 4:
                second, tree = _mutate_tree(rng, tree)
                name = f"{name}+{second}"
            name, data = f"tree {name}", _dump(tree).encode()
        yield name, data


# ---- the oracle ------------------------------------------------------------
class _Hang(Exception):
    pass


def _alarm(signum, frame):
    raise _Hang


def _outcome(load, path: Path) -> tuple[str | None, bool]:
    """(None when load(path) accepts the file or refuses it in one line,
    else what went wrong; whether it accepted the file)."""
    before = path.read_bytes()
    old = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, TIME_LIMIT_S)
    start = time.perf_counter()
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
        problem = f"no answer within {TIME_LIMIT_S} s"
    except BaseException as e:  # noqa: BLE001 - anything else is the bug
        problem = f"{type(e).__name__}: {str(e)[:300]}"
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
    if problem is None and warned:  # a line more on stderr
        problem = f"a warning: {warned[0].message}"
    if problem is None and time.perf_counter() - start > TIME_LIMIT_S:
        problem = "took longer than the time limit"
    if path.read_bytes() != before:
        problem = "the input file was changed"
    return problem, accepted


FORMATS = {
    "object file": (_object_seed, load_object_file),
    "scenario": (_scenario_seed, load_scenario),
    "library": (_library_seed, load_library),
}


class LoaderFuzzTest(unittest.TestCase):
    """MUTANTS_PER_FORMAT mutants of each format, loaded in process."""

    def test_every_mutant_accepted_or_refused_in_one_line(self):
        rng = random.Random(SEED)
        failures, counts = [], {}
        with tempfile.TemporaryDirectory() as d:
            for fmt, (seed_tree, load) in FORMATS.items():
                accepted = 0
                for n, (name, data) in enumerate(
                        mutants(seed_tree(), MUTANTS_PER_FORMAT, rng)):
                    path = Path(d) / f"{fmt.replace(' ', '_')}-{n}.yaml"
                    path.write_bytes(data)
                    problem, ok = _outcome(load, path)
                    if problem is not None:
                        failures.append(f"{fmt} #{n} ({name}): {problem}")
                    accepted += ok
                counts[fmt] = accepted
        self.assertEqual(failures, [], f"seed {SEED}")
        # The fuzzer reaches past the first check: some mutants stay valid,
        # most are refused.
        for fmt, accepted in counts.items():
            with self.subTest(fmt):
                self.assertGreater(accepted, 0)
                self.assertLess(accepted, MUTANTS_PER_FORMAT // 2)

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
    """A few mutants through the command line, with commands that refuse
    before any simulation: `objects` (never simulates), and `throw` and
    `learn` given an object file that is refused (so that a valid mutant
    scenario or library reaches no throw)."""

    def test_mutants_exit_0_or_2_with_one_line(self):
        rng = random.Random(SEED + 1)
        with tempfile.TemporaryDirectory() as d:
            d = Path(d)
            no_object = d / "no_object.yaml"
            no_object.write_text("geometries: {}\nobjects: []\n")
            runs = []
            for fmt, (seed_tree, _) in FORMATS.items():
                for n, (name, data) in enumerate(mutants(seed_tree(), 6, rng)):
                    path = d / f"{fmt.replace(' ', '_')}-{n}.yaml"
                    path.write_bytes(data)
                    args = {
                        "object file": ["objects", "--object-file", path],
                        "scenario": ["throw", "--object-file", no_object,
                                     "--scenario", path],
                        "library": ["learn", "--object-file", no_object,
                                    "--library", path],
                    }[fmt]
                    runs.append((f"{fmt} #{n} ({name})", path, data,
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
        self.assertGreaterEqual(len(runs), 15)


if __name__ == "__main__":
    unittest.main()
