"""Throws to the catch, every object, mode and search, in one picture.

    .venv/bin/python studies/throws_summary/throws_summary.py [--results DIR] [--out F]

Reads the learning-phase results `regrasp-drake table1` wrote into
models/results/ (no simulation):

    <set><mode><search>.json   set: table1 | holdout
                               mode: "" (watch first) | _ft (--first-throw)
                                     | _ar (--at-release)
                               search: "" (wavefront) | _prior (map-prior)

and draws, per object, the throws each mode needed with each search (the
watching throw counted; a bar hatched and marked ✗ where the object was not
caught: the throws made until the run's --max-throws, or until no reachable
catch point was left; the paper's throws for Table 1 as a line). Writes
<out>.png and <out>.json (the same figures as a table). A results file
that is missing is left out of the picture and named in the JSON's
"missing" list; a malformed one is refused with one line naming it.
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels
# (regrasp_drake/numerics.py), so that results match across x86-64 machines.
import regrasp_drake  # noqa: F401, I001 (first, see above)
import argparse
import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from regrasp_drake.paths import MODELS_DIR  # noqa: E402

MODES = (("", "watch first"), ("_ft", "first-throw"), ("_ar", "at release"))
SEARCHES = (("", "wavefront"), ("_prior", "map-prior"))
SETS = ("table1", "holdout")


def read_results(path: Path) -> list[dict]:
    """The rows of one results file: object, throws, caught, stopped (and
    the paper's throws for Table 1 rows). Raises SystemExit with one line
    naming the file and the field for a malformed file."""
    try:
        rows = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        sys.exit(f"{path}: not a readable JSON file ({type(e).__name__}: {e})")
    if not isinstance(rows, list):
        sys.exit(f"{path}: got a {type(rows).__name__}, expected a list of "
                 "rows as `regrasp-drake table1 --json` writes")
    out = []
    for k, row in enumerate(rows):
        for field, kind in (("object", str), ("throws", int),
                            ("caught", bool), ("stopped", str)):
            if not isinstance(row, dict) or not isinstance(row.get(field), kind):
                got = row.get(field) if isinstance(row, dict) else row
                sys.exit(f"{path}: row {k}: field {field!r} is {got!r}, "
                         f"expected a {kind.__name__}")
        paper = (row.get("paper") or {}).get("trials")  # the paper's throws
        out.append({"object": row["object"], "throws": row["throws"],
                    "caught": row["caught"], "stopped": row["stopped"],
                    "paper_throws": paper})
    return out


def collect(results_dir: Path) -> tuple[list[dict], list[str]]:
    """Every result row with its set, mode and search; and the files not
    found."""
    rows, missing = [], []
    for set_name in SETS:
        for mode_suffix, mode in MODES:
            for search_suffix, search in SEARCHES:
                path = results_dir / f"{set_name}{mode_suffix}{search_suffix}.json"
                if not path.exists():
                    missing.append(path.name)
                    continue
                for row in read_results(path):
                    rows.append(row | {"set": set_name, "mode": mode,
                                       "search": search})
    return rows, missing


def plot(rows: list[dict], path: Path) -> None:
    """One panel per mode: grouped bars per object, one bar per search."""
    objects = list(dict.fromkeys(r["object"] for r in rows))
    fig, axes = plt.subplots(len(MODES), 1, figsize=(11, 9), sharex=True)
    width = 0.38
    colours = {"wavefront": "tab:blue", "map-prior": "tab:orange"}
    for ax, (_, mode) in zip(axes, MODES):
        for s, (_, search) in enumerate(SEARCHES):
            for x, name in enumerate(objects):
                match = [r for r in rows if r["object"] == name
                         and r["mode"] == mode and r["search"] == search]
                if not match:
                    continue
                r = match[0]
                ax.bar(x + (s - 0.5) * width, r["throws"], width,
                       color=colours[search], edgecolor="k", linewidth=0.5,
                       hatch=None if r["caught"] else "//",
                       label=search if x == 0 else None)
                ax.text(x + (s - 0.5) * width, r["throws"], str(r["throws"])
                        + ("" if r["caught"] else "✗"), ha="center",
                        va="bottom", fontsize=7)
        for x, name in enumerate(objects):
            paper = next((r["paper_throws"] for r in rows
                          if r["object"] == name and r["paper_throws"]), None)
            if paper:
                ax.hlines(paper, x - width, x + width, colors="k",
                          linewidth=2, zorder=3,
                          label="paper" if x == 0 else None)
        ax.set_yscale("log")
        ax.set_ylabel("throws (log)")
        ax.set_title(mode, fontsize=10)
        ax.legend(fontsize=8, loc="upper right")
    axes[-1].set_xticks(range(len(objects)))
    axes[-1].set_xticklabels(objects, rotation=30, ha="right", fontsize=8)
    fig.suptitle("Throws to the catch (watching throw counted; ✗ and "
                 "hatched: not caught, throws made until the cap or no "
                 "reachable catch point)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--results", type=Path, default=MODELS_DIR / "results",
                        help="the directory of table1's JSON results")
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).with_name("throws_summary"),
                        help="output path without suffix (.png and .json)")
    args = parser.parse_args(argv)
    rows, missing = collect(args.results)
    if not rows:
        sys.exit(f"{args.results}: no results files (expected e.g. "
                 "table1.json from `regrasp-drake table1 --json`)")
    plot(rows, args.out.with_suffix(".png"))
    args.out.with_suffix(".json").write_text(json.dumps(
        {"rows": rows, "missing": missing}, indent=1) + "\n")
    for r in rows:
        print(f"{r['object']:24s} {r['mode']:12s} {r['search']:10s} "
              f"{r['throws']:3d} {'caught' if r['caught'] else r['stopped']}")
    print(f"wrote {args.out.with_suffix('.png')} and .json"
          + (f"; missing: {', '.join(missing)}" if missing else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
