"""Do the catch's timing parameters matter? Success maps with the state
machine's lowering speed (catch.lower_speed_m_per_s, shipped 1 m/s) or the
duration of its return (catch.return_s, shipped 0.3 s) changed, against the
shipped scenario, on 19 training objects (every third of the data set's
56, first catch point) and the five Table 1 objects.

    .venv/bin/python benchmarks/catch_timing.py [--run] [--workers N] [--out F]

Writes F (JSON, default benchmarks/catch_timing.json) and F's .png.

--run computes the maps first (`regrasp-drake dataset --catch-points 1
--scenario benchmarks/scenarios/<variant>.yaml --out
benchmarks/catch_timing/<variant>`, one variant after the other; an
interrupted run resumes), about 10 min a variant with 2 workers. Without
--run it summarizes the stored results: each variant's maps.npz,
provenance.json and samples.csv (the cells' rows are not kept).

Per variant: the wall time of its generation run (from its provenance.json,
with the shipped variant's as the reference: run them one after the other on
an otherwise idle machine for the ratio to mean anything); the catching cells
of the training maps, how many cells agree with the shipped scenario's maps
and how many two unrelated maps with the same catch rates would agree
(p·q + (1 − p)(1 − q) per map); how many training maps catch at the shipped
network's cell; and for each Table 1 object its catching cells, whether the
network's cell catches and the throws the wavefront search would take from
there (the watching throw included), counted on the map.
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
from regrasp_drake.learning.learning_phase import predict
from regrasp_drake.learning.search import attempts_to_catch, wavefront_order
from regrasp_drake.paths import MODELS_DIR
from regrasp_drake.station.mlp_system import FEATURE_NAMES, load_weights

HERE = Path(__file__).parent / "catch_timing"
SCENARIOS = Path(__file__).parent / "scenarios"
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


def training_objects() -> list[str]:
    """Every third training object of the shipped data set, in its order."""
    with np.load(MODELS_DIR / "dataset" / "maps.npz") as d:
        names = [str(n) for n in d["objects"] if "@" not in str(n)]
    return names[::3]


def run(variant: str, objects: list[str], workers: int) -> None:
    cmd = [sys.executable, "-m", "regrasp_drake.cli", "dataset", "--objects",
           *objects, "--catch-points", "1", "--workers", str(workers),
           "--out", str(HERE / variant)]
    if VARIANTS[variant] is not None:
        cmd += ["--scenario", str(VARIANTS[variant])]
    subprocess.run(cmd, check=True)


def load_maps(variant: str) -> dict:
    """{entry: boolean map} of a variant's run (its maps.npz, written when
    the run completes; empty before)."""
    path = HERE / variant / "maps.npz"
    if not path.is_file():
        return {}
    try:
        with np.load(path, allow_pickle=False) as d:
            maps = {str(n): np.asarray(m, bool)
                    for n, m in zip(d["objects"], d["caught"])}
    except (OSError, ValueError, KeyError, zipfile.BadZipFile) as e:
        raise InputError(f"{path}: unreadable ({e}); expected the maps "
                         "`regrasp-drake dataset` writes") from None
    if any(m.shape != (10, 15) for m in maps.values()):
        raise InputError(f"{path}: maps of shape other than (10, 15)")
    return maps


def _provenance(variant: str) -> dict:
    path = HERE / variant / "provenance.json"
    try:
        prov = json.loads(path.read_text())
        return {"generation_wall_s": float(prov["generation_wall_s"]),
                "entries": int(prov["entries"])}
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise InputError(f"{path}: unreadable ({e!r}); expected the "
                         "provenance `regrasp-drake dataset` writes") from None


def network_cells(entries: list[str]) -> dict:
    """The shipped network's cell for each entry, from the features of the
    entry's plan (stored by the shipped variant's run)."""
    model, _ = load_weights(MODELS_DIR / "catch_mlp.pt")
    samples = {}
    path = HERE / "shipped" / "samples.csv"
    try:
        csv = path.read_text().splitlines()
        header = csv[0].split(",")
        for line in csv[1:]:
            row = dict(zip(header, line.split(",")))
            samples[row["object"]] = [float(row[k]) for k in FEATURE_NAMES]
    except (OSError, IndexError, KeyError, ValueError) as e:
        raise InputError(f"{path}: unreadable ({e!r}); expected the samples "
                         "`regrasp-drake dataset` writes") from None
    out = {}
    for entry in entries:
        if entry in samples:
            _, (h_catch, h_down) = predict(model, samples[entry])
            out[entry] = nearest_cell(h_catch, h_down)
    return out


def throws(caught: np.ndarray, start) -> int | None:
    """The wavefront's throws from `start` to the first catching cell, the
    watching throw included (None: no cell catches)."""
    n = attempts_to_catch(wavefront_order(start), caught)
    return None if n is None else n + 1


def summarize(objects: list[str]) -> dict:
    base = load_maps("shipped")
    start = network_cells(objects + TABLE1)
    result = {}
    for variant in VARIANTS:
        maps = load_maps(variant)
        done = [e for e in objects if e in maps and e in base]
        if not done:
            continue
        prov = _provenance(variant)
        agree = sum(int((maps[e] == base[e]).sum()) for e in done)
        chance = sum(150 * (p * q + (1 - p) * (1 - q)) for p, q in
                     ((maps[e].mean(), base[e].mean()) for e in done))
        result[variant] = {
            "scenario": None if VARIANTS[variant] is None
            else str(VARIANTS[variant].relative_to(Path(__file__).parent.parent)),
            "wall_s": prov["generation_wall_s"],
            "entries": prov["entries"],
            "training": {
                "maps": len(done),
                "catching_cells": int(sum(maps[e].sum() for e in done)),
                "cells_agreeing_with_shipped": agree,
                "agreement_by_chance": round(chance),
                "network_cell_catches": int(sum(
                    bool(maps[e][start[e]]) for e in done if e in start)),
            },
            "table1": {e: {"catching_cells": int(maps[e].sum()),
                           "network_cell": list(start[e]),
                           "network_cell_catches": bool(maps[e][start[e]]),
                           "throws": throws(maps[e], start[e])}
                       for e in TABLE1 if e in maps},
        }
    ref = result.get("shipped", {}).get("wall_s")
    for r in result.values():
        r["wall_vs_shipped"] = round(r["wall_s"] / ref, 3) if ref else None
    return result


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
    b.set_ylim(0, 1.35 * 150 * t[0]["maps"])
    b.set_title("Which cells catch")
    b.legend(loc="upper right", fontsize=8)
    b.axhline(150 * t[0]["maps"], color="grey", lw=0.8)
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
        for variant in VARIANTS:
            try:
                run(variant, objects + TABLE1, args.workers)
            except subprocess.CalledProcessError as e:
                print(f"catch_timing: error: variant {variant}: `regrasp-drake "
                      f"dataset` exited with {e.returncode} (its message above)",
                      file=sys.stderr)
                return 2
    if not (HERE / "shipped" / "samples.csv").is_file():
        print(f"catch_timing: error: {HERE / 'shipped'}: no stored maps; "
              "expected the shipped variant's run (--run)", file=sys.stderr)
        return 2
    try:
        result = summarize(objects)
    except InputError as e:
        print(f"catch_timing: error: {e}", file=sys.stderr)
        return 2
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
    args.out.write_text(json.dumps(result, indent=1) + "\n")
    plot(result, args.out.with_suffix(".png"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
