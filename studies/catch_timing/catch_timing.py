"""Do the catch's timing parameters matter? Success maps with the state
machine's lowering speed (catch.lower_speed_m_per_s, shipped 1 m/s) or the
duration of its return (catch.return_s, shipped 0.3 s) changed, against the
shipped scenario, on 19 training objects (every third of the data set's
56, first catch point) and the five Table 1 objects.

    .venv/bin/python studies/catch_timing/catch_timing.py [--run] [--workers N]
        [--dir DIR] [--out F]

Writes F (JSON, default studies/catch_timing/catch_timing.json) and F's .png.

--run computes the maps first (`regrasp-drake dataset --catch-points 1
--scenario studies/catch_timing/<variant>.yaml --out DIR/<variant>`, one
variant after the other; an interrupted run resumes), about 10 min a variant
with 2 workers; give it a new DIR (the stored results are in
studies/catch_timing/catch_timing/, the default). Without --run it summarizes DIR:
each variant's maps.npz and provenance.json (the stored results keep no
cells' rows).

Per variant: the wall time of its first generation run (from its
provenance.json, with the shipped variant's as the reference: run them one
after the other, uninterrupted, on an otherwise idle machine for the ratio to
mean anything); the catching cells
of the training maps, how many cells agree with the shipped data set's maps
(models/dataset, which the shipped variant's run reproduces) and how many
two unrelated maps with the same catch rates would agree (p·q + (1 − p)(1 −
q) per map); in how many training maps the shipped network's cell catches
(its cell for the entry's plan in the shipped data set); and for each Table 1
object its catching cells, whether the network's cell (the one its `table1`
run started from) catches and the throws the wavefront search would take
from there (the watching throw included), counted on the map. A variant run
on more training objects than the 19 (`regrasp-drake dataset --objects …`
into its directory) is also compared over all of them ("all_training").
Over all the variants together ("every_variant"): the cells that catch in
every one and in none, and per Table 1 object how many variants catch at
each cell.
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels
# (regrasp_drake/numerics.py), so that results match across x86-64 machines.
import regrasp_drake  # noqa: F401, I001 (first, see above)
import argparse
import json
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np

from regrasp_drake.errors import InputError, check_output_path
from regrasp_drake.grid import nearest_cell
from regrasp_drake.learning.dataset import SHAPE
from regrasp_drake.learning.learning_phase import predict
from regrasp_drake.learning.search import attempts_to_catch, wavefront_order
from regrasp_drake.paths import MODELS_DIR
from regrasp_drake.station.mlp_system import FEATURE_NAMES, load_weights

HERE = Path(__file__).parent / "catch_timing"
SCENARIOS = Path(__file__).parent
# Variant: scenario file (None: the shipped defaults).
VARIANTS = {
    "shipped": None,
    "return_0.6s": SCENARIOS / "return_0.6s.yaml",
    "return_0.15s": SCENARIOS / "return_0.15s.yaml",
    "lower_2.0": SCENARIOS / "lower_2.0.yaml",
    "lower_0.5": SCENARIOS / "lower_0.5.yaml",
    "lower_0.25": SCENARIOS / "lower_0.25.yaml",
}
TABLE1 = [f"table1-row{k}" for k in range(1, 6)]
CELLS = SHAPE[0] * SHAPE[1]  # of a map


def training_objects() -> list[str]:
    """Every third training object of the shipped data set, in its order."""
    with np.load(MODELS_DIR / "dataset" / "maps.npz") as d:
        names = [str(n) for n in d["objects"] if "@" not in str(n)]
    return names[::3]


def run(here: Path, variant: str, objects: list[str], workers: int) -> None:
    cmd = [sys.executable, "-m", "regrasp_drake.cli", "dataset", "--objects",
           *objects, "--catch-points", "1", "--workers", str(workers),
           "--out", str(here / variant)]
    if VARIANTS[variant] is not None:
        cmd += ["--scenario", str(VARIANTS[variant])]
    subprocess.run(cmd, check=True)


def load_maps(here: Path, variant: str) -> dict:
    """{entry: boolean map} of a variant's run (its maps.npz, written when
    the run completes; empty before)."""
    path = here / variant / "maps.npz"
    if not path.is_file():
        return {}
    try:
        with np.load(path, allow_pickle=False) as d:
            maps = {str(n): np.asarray(m, bool)
                    for n, m in zip(d["objects"], d["caught"])}
    except (OSError, ValueError, KeyError, zipfile.BadZipFile) as e:
        raise InputError(f"{path}: unreadable ({e}); expected the maps "
                         "`regrasp-drake dataset` writes") from None
    if any(m.shape != SHAPE for m in maps.values()):
        raise InputError(f"{path}: maps of shape other than {SHAPE}")
    return maps


def _provenance(here: Path, variant: str) -> dict:
    path = here / variant / "provenance.json"
    try:
        prov = json.loads(path.read_text())
        # The first run made the 24 maps every variant has; a later run
        # (more training objects) is not part of the timing comparison.
        first = prov["runs"][0]
        return {"generation_wall_s": float(first["wall_s"]),
                "entries": int(first["entries_computed"])}
    except (OSError, ValueError, KeyError, TypeError, IndexError) as e:
        raise InputError(f"{path}: unreadable ({e!r}); expected the "
                         "provenance `regrasp-drake dataset` writes") from None


def network_cells(entries) -> dict:
    """The shipped network's cell for each training entry, from the features
    of its plan in the shipped data set (models/dataset/plans: every entry,
    labelled or not), and for each Table 1 object the cell its `table1` run
    started from (models/results/table1.json)."""
    model, _ = load_weights(MODELS_DIR / "catch_mlp.pt")
    out = {}
    for entry in entries:
        plan = json.loads((MODELS_DIR / "dataset" / "plans" / f"{entry}.json")
                          .read_text())
        features = [float(plan["features"][k]) for k in FEATURE_NAMES]
        out[entry] = nearest_cell(*predict(model, features)[1])
    for row in json.loads((MODELS_DIR / "results" / "table1.json").read_text()):
        out[row["object"]] = tuple(row["start_cell"])
    return out


def throws(caught: np.ndarray, start) -> int | None:
    """The wavefront's throws from `start` to the first catching cell, the
    watching throw included (None: no cell catches)."""
    n = attempts_to_catch(wavefront_order(start), caught)
    return None if n is None else n + 1


def compare(maps: dict, base: dict, entries: list[str], start: dict) -> dict:
    """A variant's maps against the shipped ones over `entries`."""
    agree = sum(int((maps[e] == base[e]).sum()) for e in entries)
    chance = sum(CELLS * (p * q + (1 - p) * (1 - q)) for p, q in
                 ((maps[e].mean(), base[e].mean()) for e in entries))
    return {"maps": len(entries),
            "catching_cells": int(sum(maps[e].sum() for e in entries)),
            "shipped_catching_cells": int(sum(base[e].sum() for e in entries)),
            "cells_agreeing_with_shipped": agree,
            "agreement_by_chance": round(chance),
            "network_cell_catches": int(sum(bool(maps[e][start[e]])
                                            for e in entries)),
            "shipped_network_cell_catches": int(sum(bool(base[e][start[e]])
                                                    for e in entries))}


def summarize(objects: list[str], here: Path = HERE) -> dict:
    """Per variant stored: its run's wall time, its maps against the shipped
    data set's over `objects` ("training") and, when it has more training
    maps, over all of them ("all_training"), and Table 1."""
    with np.load(MODELS_DIR / "dataset" / "maps.npz") as d:
        base = {str(n): m for n, m in zip(d["objects"], d["caught"])}
    start = network_cells(sorted(base))
    stored = {v: load_maps(here, v) for v in VARIANTS}
    stored = {v: maps for v, maps in stored.items()
              if any(e in maps for e in objects)}
    shipped = stored.get("shipped", {})
    result = {}
    for variant, maps in stored.items():
        done = [e for e in objects if e in maps]
        every = sorted(e for e in maps if e in base)
        prov = _provenance(here, variant)
        result[variant] = {
            "scenario": None if VARIANTS[variant] is None
            else str(VARIANTS[variant].relative_to(Path(__file__).parents[2])),
            "wall_s": prov["generation_wall_s"],
            "entries_timed": prov["entries"],
            "training": compare(maps, base, done, start),
            "table1": {e: {"catching_cells": int(maps[e].sum()),
                           "shipped_catching_cells": int(shipped[e].sum())
                           if e in shipped else None,
                           "network_cell": list(start[e]),
                           "network_cell_catches": bool(maps[e][start[e]]),
                           "throws": throws(maps[e], start[e])}
                       for e in TABLE1 if e in maps},
        }
        if len(every) > len(done):
            result[variant]["all_training"] = compare(maps, base, every, start)
    ref = result.get("shipped", {}).get("wall_s")
    for r in result.values():
        r["wall_vs_shipped"] = round(r["wall_s"] / ref, 3) if ref else None
    if result:
        result["every_variant"] = agreement_across(stored, objects, start)
    return result


def agreement_across(maps: dict, objects: list[str], start: dict) -> dict:
    """Over the variants' maps ({variant: {entry: map}}), on the entries
    every variant has: the training cells (of `objects`) that catch in every
    variant and in none, and for each Table 1 object the same with the
    number of variants in which the network's cell catches, and how many
    variants catch at each cell."""
    def counts(entry):
        return np.sum([m[entry] for m in maps.values()], axis=0)

    n = len(maps)
    common = set.intersection(*(set(m) for m in maps.values()))
    objects = [e for e in objects if e in common]
    train = np.array([counts(e) for e in objects])
    out = {"variants": list(maps), "training_maps": len(objects),
           "training_cells_catching_in_every_variant": int((train == n).sum()),
           "training_cells_catching_in_none": int((train == 0).sum()),
           "table1": {}}
    for entry in (e for e in TABLE1 if e in common):
        c = counts(entry)
        out["table1"][entry] = {
            "cells_catching_in_every_variant": int((c == n).sum()),
            "cells_catching_in_none": int((c == 0).sum()),
            "variants_in_which_the_network_cell_catches": int(c[start[entry]]),
            "variants_catching_per_cell": c.tolist()}
    return out


def plot(result: dict, path: Path) -> None:
    """Per variant: the training maps' catching cells, and the cells that
    agree with the shipped maps against agreement by chance."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(result)
    x = np.arange(len(names))
    t = [result[n]["training"] for n in names]
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4))
    a.bar(x, [r["catching_cells"] for r in t], color="tab:green")
    a.set_ylabel(f"catching cells, {t[0]['maps']} training maps")
    a.set_title("How often the catch works")
    b.bar(x - 0.2, [r["cells_agreeing_with_shipped"] for r in t], 0.4,
          label="cells agreeing with the shipped maps")
    b.bar(x + 0.2, [r["agreement_by_chance"] for r in t], 0.4,
          label="agreement of unrelated maps (same catch rates)")
    b.set_ylim(0, 1.35 * CELLS * t[0]["maps"])
    b.set_title("Which cells catch")
    b.legend(loc="upper right", fontsize=8)
    b.axhline(CELLS * t[0]["maps"], color="grey", lw=0.8)
    for ax in (a, b):
        ax.set_xticks(x, names, rotation=20)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--run", action="store_true",
                   help="compute the variants' maps first (resumable)")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--dir", type=Path, default=HERE, metavar="DIR",
                   help="where each variant's run lives, DIR/<variant> "
                        "(default: the stored results)")
    p.add_argument("--out", type=Path, default=HERE.with_suffix(".json"))
    args = p.parse_args(argv)
    try:
        check_output_path("--out", args.out)
        if args.workers < 1:
            raise InputError(f"--workers: {args.workers}: expected at least 1")
    except InputError as e:
        print(f"catch_timing: error: {e}", file=sys.stderr)
        return 2
    objects = training_objects()
    if args.run:
        stored = [v for v in VARIANTS if (args.dir / v / "maps.npz").is_file()
                  and not (args.dir / v / "cells").is_dir()]
        if stored:
            print(f"catch_timing: error: --dir: {args.dir / stored[0]} holds "
                  "stored results without their cells' rows; expected a new "
                  "directory (or a run of this script's) for --run",
                  file=sys.stderr)
            return 2
        for variant in VARIANTS:
            try:
                run(args.dir, variant, objects + TABLE1, args.workers)
            except subprocess.CalledProcessError as e:
                print(f"catch_timing: error: variant {variant}: `regrasp-drake "
                      f"dataset` exited with {e.returncode} (its message above)",
                      file=sys.stderr)
                return 2
    if not (args.dir / "shipped" / "maps.npz").is_file():
        print(f"catch_timing: error: {args.dir / 'shipped'}: no stored maps; "
              "expected the shipped variant's run (--run)", file=sys.stderr)
        return 2
    try:
        result = summarize(objects, args.dir)
    except InputError as e:
        print(f"catch_timing: error: {e}", file=sys.stderr)
        return 2
    every = result.pop("every_variant")
    for variant, r in result.items():
        t = r["training"]
        rows = ", ".join(
            f"{v['catching_cells']}{'' if v['network_cell_catches'] else '*'}"
            for v in r["table1"].values())
        print(f"{variant:12s} wall {r['wall_s']:6.0f} s ({r['wall_vs_shipped']}×), "
              f"training {t['maps']} maps: {t['catching_cells']} catching cells, "
              f"{t['cells_agreeing_with_shipped']} agree with shipped "
              f"(chance {t['agreement_by_chance']}), network cell catches in "
              f"{t['network_cell_catches']}; Table 1 catching cells {rows} "
              "(*: the network's cell drops)")
        if "all_training" in r:
            a = r["all_training"]
            print(f"{'':12s} all {a['maps']} training maps: "
                  f"{a['catching_cells']} catching cells (shipped "
                  f"{a['shipped_catching_cells']}), {a['cells_agreeing_with_shipped']}"
                  f" agree (chance {a['agreement_by_chance']}), network cell "
                  f"catches in {a['network_cell_catches']} (shipped "
                  f"{a['shipped_network_cell_catches']})")
    print(f"over all {len(every['variants'])} variants: "
          f"{every['training_cells_catching_in_every_variant']} of "
          f"{CELLS * every['training_maps']} training cells catch in every one, "
          f"{every['training_cells_catching_in_none']} in none; Table 1 "
          "(every / none / the network's cell in): " + ", ".join(
              f"{t['cells_catching_in_every_variant']} / "
              f"{t['cells_catching_in_none']} / "
              f"{t['variants_in_which_the_network_cell_catches']}"
              for t in every["table1"].values()))
    plot(result, args.out.with_suffix(".png"))
    args.out.write_text(json.dumps(result | {"every_variant": every},
                                   indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
