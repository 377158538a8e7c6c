"""Pictures of an episode: the sensors over time (the paper's Fig. 11) and the
object's flight."""

from pathlib import Path

import numpy as np

from regrasp_drake import atomic_io
from regrasp_drake.grid import ending, ending_counts
from regrasp_drake.learning.labels import SHAPE, label_cell
from regrasp_drake.parameter_space import (
    ENDINGS,
    H_CATCH_VALUES,
    H_DOWN_VALUES,
)
from regrasp_drake.planning.grasp import describe_grasp
from regrasp_drake.station.catch_state_machine import Phase


def _pyplot():
    """matplotlib's pyplot, drawing to files (Agg), imported when a picture
    is drawn: 0.4 s that importing the API (regrasp_drake.api, which every
    command does) does not pay."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def plot_episode(result, path: Path) -> Path:
    """Writes a PNG: palm IR 1-3, the nearest approach IR and the bumper over
    time, the phases shaded; and the object's height and axis tilt."""
    plt = _pyplot()
    logs = result.logs
    t = logs.t
    fig, axes = plt.subplots(3, 1, figsize=(9, 9), sharex=True)
    ax = axes[0]
    for i in range(3):
        ax.plot(t, logs.ir[i], label=f"IR {i + 1} (palm)")
    ax.plot(t, logs.ir[3:].min(axis=0), "k--", label="min IR 4-13 (approach)")
    ax.set_ylabel("infrared level [0-1000]")
    ax.legend(loc="lower left", fontsize=8)
    ax.set_title(f"{result.object}: {result.outcome}"
                 + (f" (h_catch {result.h_catch:.2f} m, h_down "
                    f"{result.h_down:.2f} m)" if result.h_catch is not None
                    else "")
                 + (f"\nstart: {describe_grasp(result.start_grasp)}"
                    f"; {result.regrasp_line()}" if result.target else ""))
    axes[1].step(t, logs.bumper, where="post", color="tab:orange")
    axes[1].set_ylabel("tactile bumper")
    axes[1].set_ylim(-0.1, 1.1)
    p = logs.object_state[4:7]
    axes[2].plot(t, p[2], label="object height z [m]")
    axes[2].plot(t, logs.object_state[12], label="object vertical velocity [m/s]")
    axes[2].set_xlabel("time [s]")
    axes[2].legend(loc="lower left", fontsize=8)
    for ax in axes:
        _shade_phases(ax, t, logs.phase)
        ax.grid(alpha=0.3)
    fig.tight_layout()
    atomic_io.save_figure(fig, path, dpi=90)
    plt.close(fig)
    return Path(path)


def _shade_phases(ax, t, phase):
    plt = _pyplot()
    colors = plt.cm.Pastel1(np.linspace(0, 1, len(Phase)))
    start = 0
    for k in range(1, len(t) + 1):
        if k == len(t) or phase[k] != phase[start]:
            ph = Phase(int(phase[start]))
            ax.axvspan(t[start], t[min(k, len(t) - 1)], color=colors[ph],
                       alpha=0.5, lw=0)
            if ax is ax.figure.axes[0]:
                ax.text(t[start], 1010, ph.name.lower(), fontsize=7)
            start = k


# The colour of each of ENDINGS in the maps below.
ENDING_COLOURS = {"caught": "#2ca02c", "wrong_grasp": "#bcbd22",
                  "in_fingers": "#9467bd",
                  "on_arm": "#d62728", "loose": "#ff7f0e",
                  "below_palm": "#1f77b4", "near_ground": "#17becf",
                  "failed": "#8c564b", "other": "#7f7f7f"}


def draw_endings(ax, rows: dict, *, marks=()) -> None:
    """Draws a success map on `ax`: h_down across, h_catch up (m), each cell
    coloured by how its episode ended (grid.ending), white where it has not
    run; `marks`: (cell, colour) pairs framed on top."""
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Rectangle

    keys = list(ENDINGS)
    cmap = ListedColormap([ENDING_COLOURS[k] for k in keys])
    cmap.set_bad("white")
    grid = np.full((len(H_CATCH_VALUES), len(H_DOWN_VALUES)), np.nan)
    for (i, j), row in rows.items():
        grid[i, j] = keys.index(ending(row))
    ax.imshow(np.ma.masked_invalid(grid), origin="lower", cmap=cmap,
              vmin=-0.5, vmax=len(keys) - 0.5, aspect="auto")
    ax.set_xticks(range(0, len(H_DOWN_VALUES), 2),
                  [f"{v:.2f}" for v in H_DOWN_VALUES[::2]], fontsize=7,
                  rotation=60)
    ax.set_yticks(range(len(H_CATCH_VALUES)),
                  [f"{v:.2f}" for v in H_CATCH_VALUES], fontsize=7)
    ax.set_xlabel("h_down [m]", fontsize=8)
    ax.set_ylabel("h_catch [m]", fontsize=8)
    for (i, j), colour in marks:
        ax.add_patch(Rectangle((j - 0.5, i - 0.5), 1, 1, fill=False,
                               edgecolor=colour, linewidth=2.5))


def ending_legend(keys=None, extra=()) -> list:
    """Legend handles for draw_endings' colours (every ending, or `keys`),
    then `extra` (label, colour) pairs for framed cells."""
    from matplotlib.patches import Patch

    return ([Patch(color=ENDING_COLOURS[k], label=ENDINGS[k])
             for k in (keys or ENDINGS)]
            + [Patch(facecolor="none", edgecolor=colour, label=label)
               for label, colour in extra])


def plot_success_map(rows: dict, path: Path, *, title: str) -> Path:
    """`regrasp-drake grid --plot`: one map coloured by ending, its label
    (the data set's rule: the catching cell farthest from any failed cell,
    learning/labels.label_cell) framed, with the count of each ending."""
    plt = _pyplot()
    counts = ending_counts(rows.values())
    fig, ax = plt.subplots(figsize=(7.5, 6.2))
    caught = np.zeros(SHAPE, bool)
    for cell, row in rows.items():
        caught[cell] = row["outcome"] == "caught"
    label = label_cell(caught) if len(rows) == caught.size else None
    draw_endings(ax, rows, marks=[(label, "gold")] if label else ())
    shown = [k for k in ENDINGS if counts[k]]
    handles = ending_legend(shown, [("label: the catching cell farthest "
                                     "from any failed one", "gold")]
                            if label else ())
    for handle, key in zip(handles, shown):
        handle.set_label(f"{counts[key]:>3}  {handle.get_label()}")
    fig.legend(handles=handles, loc="lower center", ncol=1, fontsize=7.5)
    ax.set_title(f"{title}\n{counts['caught']} of {len(rows)} cells catch",
                 fontsize=10)
    fig.tight_layout(rect=(0, 0.06 + 0.035 * len(handles), 1, 1))
    atomic_io.save_figure(fig, path, dpi=110)
    plt.close(fig)
    return Path(path)
