"""What the commands write, and whether an existing file there is ours to
overwrite or resume: every output argument of every command with what it
holds, the outputs' defaults under --out-dir, and the checks that run
before any work (`check_outputs`: a file that could not be written, that is
another output or an input, or that exists and is not of the kind the
command writes, is refused in one line naming the argument).

tests/test_cli.py holds every Path argument of every command to being in
OUTPUTS or INPUTS.
"""

import io
from pathlib import Path

from regrasp_drake.errors import InputError, check_output_path, quote


class InOutDir:
    """The default of an output argument: a file or directory name under
    the command's --out-dir (filled in by fill_defaults; `{entry}` stands
    for the map's entry, grid_entry; `{trained}` for what train trains,
    trained_name). Not a str: argparse would convert
    it with the argument's type."""

    def __init__(self, name: str):
        self.name = name


def grid_entry(args) -> str:
    """The entry `grid` maps, named as `dataset` names it: <object>, or
    <object>@K for the K-th catch point."""
    from regrasp_drake.world.objects import resolve_object
    obj = resolve_object(name=args.object, file=args.object_file)
    if args.catch_point < 1:
        raise InputError(f"--catch-point: got {args.catch_point}, expected "
                         ">= 1")
    return obj.name + ("" if args.catch_point == 1 else f"@{args.catch_point}")


def trains_planner(args) -> bool:
    """Whether `train` trains the learned planner (--network planner, the
    default under --target) rather than the paper's network."""
    if getattr(args, "command", None) != "train":
        return False
    network = args.network or ("planner" if args.target else "paper")
    return network == "planner"


def trained_name(args) -> str:
    """What `train` writes given no --out: catch_mlp.pt (the paper's
    network), or the target's planner, planner_flip+0.json, …"""
    if not trains_planner(args):
        return "catch_mlp.pt"
    from regrasp_drake.learning.planner import planner_file_name
    return planner_file_name(args.target, args.offset_mm or 0.0)


def train_files(out: Path) -> tuple[Path, Path]:
    """The report (F.json) and the training curve (F_training.png) `train`
    writes beside the weights F."""
    return out.with_suffix(".json"), out.with_name(out.stem + "_training.png")


# Every argument that names a file or directory a command writes, with what
# it holds: that says when an existing one is ours to overwrite or resume
# (_check_ours). tests/test_cli.py holds every Path argument of every command
# to being here or in INPUTS.
OUTPUTS = {
    "catch": {"html": "replay", "json": "json", "plot": "plot"},
    "grid": {"out": "map", "plot": "plot"},
    "throw": {"json": "json", "plot": "plot"},
    "diagram": {"out": "diagram"},
    "learn": {"library": "library", "html": "replay", "json": "json",
              "plot": "plot"},
    "regrasp": {"library": "library", "html": "replay", "json": "json",
                "plot": "plot"},
    "apply": {"html": "replay", "json": "json"},
    "dataset": {"out": "data set"},
    "train": {"out": "weights", "json": "json"},
    "table1": {"library": "library", "json": "json", "markdown": "table",
               "maps_dir": "maps"},
    "train-flight": {"out": "flight model"},
    "train-offset": {"out": "offset prior"},
}
# What the directories a command makes hold.
DIRECTORIES = ("data set", "data sets", "maps", "outputs")
# The arguments that name a file or directory a command reads (and `apply`'s
# --library); --out-dir holds the outputs given no path.
INPUTS = ("object_file", "scenario", "weights", "flight_model", "data",
           "offset_prior")
def fill_defaults(args) -> None:
    """Puts every output given no path (an InOutDir default) under
    --out-dir (default paths.OUT_DIR); sets args.out_dir to that directory
    when an output went there, else to None (main makes it once every
    output is checked)."""
    from regrasp_drake.paths import OUT_DIR
    out_dir = getattr(args, "out_dir", None) or OUT_DIR
    used = False
    for dest, value in list(vars(args).items()):
        if not isinstance(value, InOutDir):
            continue
        if dest == "maps_dir" and args.no_maps:
            setattr(args, dest, None)
            continue
        name = value.name
        if "{entry}" in name:
            name = name.format(entry=grid_entry(args))
        if "{trained}" in name:
            name = name.format(trained=trained_name(args))
        setattr(args, dest, out_dir / name)
        used |= dest in OUTPUTS.get(args.command, {})
    if "out_dir" in vars(args):
        args.out_dir = out_dir if used else None


def _outputs(args) -> dict:
    """{label: (path, what it holds)} of everything the command writes: the
    outputs its arguments name (labelled with the flag), the files it
    writes beside them (the flag and which file), and --out-dir when an
    output went there."""
    outputs = {}

    def add(label, path, holds):
        outputs[label] = (Path(path), holds)
        for which, (other, other_holds) in _beside(args, path, holds).items():
            add(f"{label} ({which})", other, other_holds)

    if getattr(args, "out_dir", None) is not None:
        add("--out-dir", args.out_dir, "outputs")
    for dest, holds in OUTPUTS.get(args.command, {}).items():
        if holds == "data set" and getattr(args, "all_targets", False):
            holds = "data sets"  # --out holds one data set per target
        if holds == "weights" and trains_planner(args):
            holds = "planner"
        if getattr(args, dest, None) is not None:
            add("--" + dest.replace("_", "-"), getattr(args, dest), holds)
    return outputs


def _beside(args, path, holds) -> dict:
    """{which: (path, what it holds)} of the files a command writes beside
    an output (or, for --maps-dir, in it)."""
    if holds == "map":
        from regrasp_drake.map_rows import plan_path
        return {"its plan": (plan_path(path), "json")}
    if holds == "weights":
        report_json, curve_png = train_files(path)
        return {"its report": (report_json, "json"),
                "its training curve": (curve_png, "plot")}
    if holds == "flight model":
        from regrasp_drake.learning.flight_predictor import report_path
        return {"its report": (report_path(path), "json")}
    if holds == "data sets":
        from regrasp_drake.learning.dataset import TARGET_SETS, target_dir_name
        return {target_dir_name(t): (Path(path) / target_dir_name(t),
                                     "data set") for t in TARGET_SETS}
    if holds == "maps":
        from regrasp_drake.learning.table1 import map_paths, object_names
        files = {}
        for name in object_names(args.objects):
            rows, png = map_paths(path, name)
            files[f"{name}'s map"] = (rows, "map")
            files[f"{name}'s plot"] = (png, "plot")
        return files
    return {}


def check_outputs(args) -> None:
    """Refuses, before any work (InputError naming the argument), an output
    that could not be written (errors.check_output_path: a file's directory
    must exist, or be one the command makes, and be writable), that is
    another output or an input of the command, or that exists and is not
    ours (_check_ours)."""
    outputs = _outputs(args)
    made = {path for path, holds in outputs.values() if holds in DIRECTORIES}
    for label, (path, holds) in outputs.items():
        if (holds not in DIRECTORIES and path.parent in made
                and not path.parent.exists()):
            continue  # in a directory the command makes, checked as one
        check_output_path(label, path, makes_directory=holds in DIRECTORIES)
    inputs = {"--" + name.replace("_", "-"): getattr(args, name)
              for name in INPUTS if isinstance(getattr(args, name, None), Path)}
    if args.command == "apply":
        inputs["--library"] = args.library
    seen = {}
    for label, (path, holds) in outputs.items():
        if holds == "outputs":
            continue
        for other, other_path in list(seen.items()) + list(inputs.items()):
            if _same_path(path, other_path):
                what = "output" if other in seen else "input"
                raise InputError(f"{label}: got {quote(str(path))}, the same "
                                 f"path as the {what} {other}, expected "
                                 "another path")
        seen[label] = path
    for label, (path, holds) in outputs.items():
        _check_ours(label, path, holds)


def _same_path(a: Path, b: Path) -> bool:
    """a and b name the same file (through links too)."""
    return Path(a).resolve() == Path(b).resolve()


# What an existing output holds when it is ours (a file of that kind the
# command may overwrite), and the test of it: None when it is, else why not.
_OURS = {
    "json": ("JSON", lambda path: _refusal(_load_json, path)),
    "library": ("a regrasp library", lambda path: _refusal(_load_library, path)),
    "replay": ("a Meshcat replay", lambda path: _replay_reason(path)),
    "table": ("a table this command wrote", lambda path: _table_reason(path)),
    "plot": ("a plot matplotlib wrote", lambda path: _plot_reason(path)),
    "weights": ("a network's weights file",
                lambda path: _refusal(_load_weights, path)),
    "flight model": ("a flight predictor",
                     lambda path: _refusal(_load_flight_model, path)),
    "diagram": ("a Graphviz digraph", lambda path: _diagram_reason(path)),
    "offset prior": ("an offset prior",
                     lambda path: _refusal(_load_offset_prior, path)),
    "planner": ("a learned planner",
                lambda path: _refusal(_load_planner, path)),
}


def _check_ours(label: str, path: Path, holds: str) -> None:
    """Refuses an existing output that is not ours: a map without its
    F.plan.json beside it or with a malformed row (_check_map); a data set
    directory that holds no data set; a file that is not what the output
    holds (_OURS: a --json that is not JSON, a --plot matplotlib did not
    write, …). New and empty files, and devices such as /dev/null, are
    fine. And a plot whose extension matplotlib cannot write."""
    if holds == "plot":
        _check_plot_extension(label, path)
    if holds == "data set":
        _check_dataset_dir(label, path)
    if holds in DIRECTORIES or not path.exists():
        return
    if holds == "map":
        _check_map(label, path)
        return
    if not path.is_file() or not path.stat().st_size:
        return
    what, reason = _OURS[holds][0], _OURS[holds][1](path)
    if reason is not None:
        raise InputError(f"{label}: got {quote(str(path))}, an existing file "
                         f"that is not {what} (not ours: {reason}), expected "
                         f"a new file or {what} to overwrite")


def _refusal(load, path) -> str | None:
    """None when load(path) reads the file, else its refusal."""
    try:
        load(path)
    except InputError as e:
        return str(e)
    return None


def _load_json(path):
    from regrasp_drake.input_files import load_json
    return load_json(path)


def _load_library(path):
    from regrasp_drake.learning.library import load_library
    return load_library(path)


def _load_planner(path):
    from regrasp_drake.learning.planner import SuccessModel
    return SuccessModel.load(path)


def _load_weights(path):
    from regrasp_drake.station.mlp_system import load_weights
    return load_weights(path)


def _load_flight_model(path):
    from regrasp_drake.learning.flight_predictor import FlightPredictor
    return FlightPredictor.load(path)


def _load_offset_prior(path):
    from regrasp_drake.learning.offset_prior import OffsetPrior
    return OffsetPrior.load(path)


def _replay_reason(path: Path) -> str | None:
    """A Meshcat page (Meshcat.StaticHtml) has its title in its first lines."""
    with open(path, "rb") as f:
        head = f.read(4096)
    if b"<title>Drake MeshCat</title>" in head:
        return None
    return "no <title>Drake MeshCat</title> in its first 4096 bytes"


def _diagram_reason(path: Path) -> str | None:
    """Drake's Graphviz text begins with `digraph`."""
    with open(path, "rb") as f:
        head = f.read(64)
    return None if head.startswith(b"digraph") else "it does not begin with digraph"


def _table_reason(path: Path) -> str | None:
    from regrasp_drake.input_files import read_text
    from regrasp_drake.learning.table1 import format_markdown
    header = format_markdown([]).splitlines()[0]
    try:
        text = read_text(path, "Markdown table")
    except InputError as e:
        return str(e)
    return (None if text.startswith(header)
            else "its first line is not the table's header")


def _plot_reason(path: Path) -> str | None:
    """matplotlib names itself in the PNG, PDF, SVG and PostScript files it
    writes; it leaves no mark in the other formats (JPEG, TIFF, …), whose
    existing files are therefore never overwritten."""
    import gzip
    import zlib

    from regrasp_drake.input_files import read_bytes
    try:
        data = read_bytes(path, "plot")
        if path.suffix.lower() == ".svgz":
            data = gzip.GzipFile(fileobj=io.BytesIO(data)).read(len(data) * 20)
    except (InputError, OSError, EOFError, zlib.error) as e:
        return str(e)
    if b"matplotlib" in data.lower():
        return None
    if path.suffix.lower() in (".png", ".pdf", ".svg", ".svgz", ".eps", ".ps"):
        return "no mark of matplotlib in it"
    return (f"matplotlib leaves no mark in a {path.suffix} file, so this "
            "command cannot tell one it wrote")


def _check_map(label: str, path: Path) -> None:
    """A map (grid's --out, table1's maps) is ours only with its F.plan.json
    beside it, and resumed only with every row whole (a malformed row is
    refused naming its line; a last line cut by a kill is computed again)."""
    from regrasp_drake.map_rows import plan_path, read_rows
    if path.is_file() and path.stat().st_size and not plan_path(path).exists():
        raise InputError(
            f"{label}: got {quote(str(path))}, an existing file without "
            f"{plan_path(path).name} beside it (not a map this command "
            "began), expected a new file or a map to resume")
    try:
        read_rows(path)
    except InputError as e:
        raise InputError(f"{label}: {e}") from None


def _check_plot_extension(label: str, path: Path) -> None:
    import shutil

    import matplotlib
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    kinds = set(FigureCanvasAgg.get_supported_filetypes())
    if not shutil.which(matplotlib.rcParams["pgf.texsystem"]):
        kinds.discard("pgf")  # written through a TeX system, absent here
    if path.suffix.lower().lstrip(".") not in kinds:
        raise InputError(f"{label}: got {quote(str(path))}, expected a file "
                         "name ending in one of "
                         f"{', '.join('.' + k for k in sorted(kinds))}")


def _check_dataset_dir(label: str, path: Path) -> None:
    """A data set's directory is ours when new, empty, or holding what
    `dataset` writes."""
    if not path.is_dir() or not any(path.iterdir()):
        return
    if not any((path / name).exists() for name in
               ("provenance.json", "scenario.yaml", "cells", "plans",
                "dataset.lock")):
        raise InputError(f"{label}: got {quote(str(path))}, an existing "
                         "directory that holds no data set, expected a new "
                         "or empty directory or a data set to resume")
