"""Where a data set's entries come from, recorded and checked: the scenario
they are computed with, the robot's model files, the code's version, the
runs that computed them (provenance.json, learning/dataset_files.py). A
data set is resumed only under the scenario and models it was begun with
(`check_same_scenario`)."""

import hashlib
import subprocess
from pathlib import Path

from regrasp_drake import atomic_io, numerics
from regrasp_drake.errors import InputError
from regrasp_drake.input_files import parse_yaml, read_text
from regrasp_drake.learning.dataset_files import load_provenance
from regrasp_drake.paths import PACKAGE_DIR, REPO_DIR, SDF_DIR
from regrasp_drake.station.scenario import (
    load_scenario,
    scenario_digest,
    scenario_yaml,
)

# The robot's model files (the arm, the hand and their directives), which
# the scenario names by path only: a data set records their digest.
MODELS_FILE = "robot_models.sha256"


def robot_models_digest() -> str:
    """A sha256 of sdf/'s robot model files (*.sdf, *.dmd.yaml; the
    objects have the catalogue's hash)."""
    digest = hashlib.sha256()
    sdf = SDF_DIR
    for path in sorted(list(sdf.glob("*.sdf")) + list(sdf.glob("*.dmd.yaml"))):
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def scenario_text(scenario=None) -> str:
    """The scenario as the data set records it (its every value, YAML);
    None: the shipped one."""
    return scenario_yaml(scenario or load_scenario())


def check_same_scenario(out_dir: Path, scenario=None) -> None:
    """Entries are resumed and assembled only under the scenario they were
    computed with: the one in out_dir's provenance.json, or, before a run
    has finished, in its scenario.yaml (written here for a new data set).
    Another one is refused (InputError naming --scenario and the first
    field that differs): resuming would mix two scenarios' maps under one
    provenance. A text written before a field existed is the same scenario
    when its digest is (scenario_digest leaves out a field at the value that
    behaves as before it, e.g. catch.closing_order "together"). So are other
    robot model files (sdf/, which the scenario names by path only), when
    the data set recorded their digest."""
    _check_same_models(out_dir)
    current = scenario_text(scenario)
    provenance, started = out_dir / "provenance.json", out_dir / "scenario.yaml"
    stored = None
    if provenance.exists():
        try:
            stored = load_provenance(provenance).get("scenario")
        except InputError as e:
            raise InputError(f"--out: {e}") from None
        if stored is None:
            raise InputError(f"--out: {provenance}: no scenario text, "
                             "expected the data set's provenance")
    elif started.exists():
        stored = read_text(started, "scenario YAML file")
    if stored is None:
        out_dir.mkdir(parents=True, exist_ok=True)
        atomic_io.write_text(started, current)
        return
    if stored != current and not _same_digest(stored, scenario):
        try:
            a = parse_yaml(stored, tags=True)
        except InputError as e:
            raise InputError(f"--out: {out_dir}: the data set's scenario is "
                             f"{e}") from None
        a = a if isinstance(a, dict) else {}
        field, old, new = _first_difference(
            a, parse_yaml(current, tags=True) or {})
        raise InputError(
            f"--scenario: {field} is {new!r} here but {old!r} in the data set "
            f"in {out_dir} (computed with another scenario), expected the "
            "same scenario to resume it, or another --out")


def _same_digest(stored: str, scenario) -> bool:
    """Whether the scenario text `stored` digests as `scenario` (None: the
    shipped one); False when it no longer loads."""
    try:
        then = load_scenario(text=stored)
    except InputError:
        return False
    return scenario_digest(then) == scenario_digest(scenario or load_scenario())


def _check_same_models(out_dir: Path) -> None:
    """InputError when out_dir's entries were computed with other robot
    model files than sdf/'s now (the digest in its provenance.json, or in
    robot_models.sha256 before its first run finished; a new data set gets
    that file). A data set that recorded none is not checked."""
    current = robot_models_digest()
    provenance, started = out_dir / "provenance.json", out_dir / MODELS_FILE
    if provenance.exists():
        try:
            stored = load_provenance(provenance).get("robot_models_sha256")
        except InputError as e:
            raise InputError(f"--out: {e}") from None
    elif started.exists():
        stored = read_text(started, "digest file").strip()
    else:
        if not (out_dir / "scenario.yaml").exists():  # a new data set
            out_dir.mkdir(parents=True, exist_ok=True)
            atomic_io.write_text(started, current + "\n")
        return
    if stored is not None and stored != current:
        raise InputError(
            f"sdf/: the robot models (*.sdf, *.dmd.yaml) have digest "
            f"{current} here but {stored} in the data set in {out_dir} "
            "(computed with other models), expected the same models to "
            "resume it, or another --out")


def _first_difference(a, b, prefix=""):
    """(dotted field, a's value, b's value) of the first field where two
    parsed YAML mappings differ."""
    for key in sorted(set(a) | set(b), key=str):
        x, y = a.get(key), b.get(key)
        if x == y:
            continue
        if isinstance(x, dict) and isinstance(y, dict):
            return _first_difference(x, y, f"{prefix}{key}.")
        return f"{prefix}{key}", x, y
    return prefix.rstrip(".") or "scenario", a, b


def runs(out_dir: Path, provenance: dict) -> list[dict]:
    """The generation runs that computed the entries of out_dir, oldest
    first: those of the provenance.json already there (a file written
    before runs were kept counts as one run of all its entries), and this
    run, when it computed an entry."""
    runs = []
    path = out_dir / "provenance.json"
    if path.exists():
        old = load_provenance(path)
        runs = old.get("runs")
        if runs is None:
            runs = [] if old.get("generation_wall_s") is None else [{
                "wall_s": old["generation_wall_s"],
                "entries_computed": old.get("entries"),
                "workers": old.get("workers"), "backend": old.get("backend"),
                "code_version": old.get("code_version")}]
    if provenance["entries_computed"]:
        runs = runs + [{k: provenance[k] for k in (
            "code_version", "workers", "backend")} | {
            "wall_s": provenance["generation_wall_s"],
            "entries_computed": provenance["entries_computed"],
            "numerics": numerics.status()}]
    return runs


def code_version() -> str:
    """The git commit (when known) and a hash of the package's and models'
    source files, which identifies uncommitted code too."""
    digest = hashlib.sha256()
    # Named as in the checkout (regrasp_drake/…, sdf/…) wherever the
    # package runs, so that an installed copy hashes as its checkout does.
    files = sorted([(Path("regrasp_drake", p.relative_to(PACKAGE_DIR)), p)
                    for p in PACKAGE_DIR.rglob("*.py")]
                   + [(Path("sdf", p.relative_to(SDF_DIR)), p)
                      for p in SDF_DIR.rglob("*.*")])
    for name, path in files:
        digest.update(str(name).encode())
        digest.update(path.read_bytes())
    return git_version() + " sources-sha256:" + digest.hexdigest()[:16]


def git_version() -> str:
    """The repository's commit, with "+dirty" when its code or models have
    uncommitted changes; "unknown" outside a git checkout."""
    if REPO_DIR is None:  # installed: no checkout to ask
        return "unknown"
    try:
        commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=REPO_DIR,
                                capture_output=True, text=True, check=True)
        dirty = subprocess.run(["git", "status", "--porcelain", "--",
                                "regrasp_drake", "sdf"], cwd=REPO_DIR,
                               capture_output=True, text=True, check=True)
        return commit.stdout.strip() + ("+dirty" if dirty.stdout.strip() else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
