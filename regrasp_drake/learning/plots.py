"""Pictures of the learning phase: the search over the parameter space (the
paper's Fig. 7) and the watched flight with its catch points."""

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Patch, Rectangle  # noqa: E402

from regrasp_drake import atomic_io
from regrasp_drake.parameter_space import H_CATCH_VALUES, H_DOWN_VALUES  # noqa: E402

OUTCOME_COLOURS = {"caught": "tab:green", "dropped": "tab:red",
                   "timeout": "tab:orange", "landed": "tab:purple",
                   "failed": "tab:gray", "wrong_grasp": "tab:olive"}


def plot_search(attempts, start_cell, path, *, title: str = "",
                success_map: dict | None = None) -> Path:
    """Writes the search as a PNG: the 15 × 10 grid (h_down across, h_catch
    up, in m), the start cell framed in yellow, each tried cell numbered in
    the order it was tried (1 = throw 2, the network's cell) and coloured by
    its outcome.

    attempts: dicts or objects with `cell` (i_catch, i_down) and `outcome`.
    success_map: optional {cell: {"outcome": …}} of every cell (from
    `regrasp-drake grid`), drawn faintly under the cells not tried."""
    n_catch, n_down = len(H_CATCH_VALUES), len(H_DOWN_VALUES)
    fig, ax = plt.subplots(figsize=(9, 5.6))
    tried = {}
    for k, a in enumerate(attempts, 1):
        cell = tuple(_get(a, "cell"))
        tried[cell] = (k, _get(a, "outcome"))
    for i in range(n_catch):
        for j in range(n_down):
            face, alpha = "white", 1.0
            if (i, j) in tried:
                face = OUTCOME_COLOURS.get(tried[(i, j)][1], "black")
            elif success_map and (i, j) in success_map:
                face = OUTCOME_COLOURS.get(success_map[(i, j)]["outcome"],
                                           "black")
                alpha = 0.18
            ax.add_patch(Rectangle((j - 0.5, i - 0.5), 1, 1, facecolor=face,
                                   alpha=alpha, edgecolor="0.7", lw=0.8))
            if (i, j) in tried:
                ax.text(j, i, str(tried[(i, j)][0]), ha="center",
                        va="center", fontsize=9, color="white",
                        fontweight="bold")
    i, j = start_cell
    ax.add_patch(Rectangle((j - 0.5, i - 0.5), 1, 1, fill=False,
                           edgecolor="gold", lw=3.5))
    ax.set_xlim(-0.5, n_down - 0.5)
    ax.set_ylim(-0.5, n_catch - 0.5)
    ax.set_aspect("equal")
    ax.set_xticks(range(n_down), [f"{v:.2f}" for v in H_DOWN_VALUES],
                  rotation=60, fontsize=8)
    ax.set_yticks(range(n_catch), [f"{v:.2f}" for v in H_CATCH_VALUES],
                  fontsize=8)
    ax.set_xlabel("h_down [m]")
    ax.set_ylabel("h_catch [m]")
    outcomes = sorted({o for _, o in tried.values()}
                      | ({r["outcome"] for r in success_map.values()}
                         if success_map else set()))
    handles = [Patch(facecolor="white", edgecolor="gold", lw=3,
                     label="start cell (network)")]
    handles += [Patch(color=OUTCOME_COLOURS.get(o, "black"), label=o)
                for o in outcomes]
    if success_map:
        handles.append(Patch(color="0.85", label="faint: map, not tried"))
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1),
              fontsize=8)
    ax.set_title((title or f"search: {len(tried)} cells tried")
                 + "\ncells numbered in the order tried (1: the network's "
                   "cell, throw 2)", fontsize=10)
    fig.tight_layout()
    atomic_io.save_figure(fig, path, dpi=100)
    plt.close(fig)
    return Path(path)


def plot_flight(observation, scenario, path) -> Path:
    """Writes a PNG of the watched flight: the object's height and vertical
    velocity, and how far its axis is from horizontal (|y_O · z_W|), with the
    catch height band, the tilt tolerance and the catch points (the one
    used filled)."""
    logs = observation.watched.logs
    t, z, v = logs.t, logs.object_state[6], logs.object_state[12]
    y_z = np.array([_axis_z(logs.object_state[:4, k]) for k in range(len(t))])
    c = scenario.catch
    used = observation.plan.catch_point.t_s if observation.plan else None
    fig, axes = plt.subplots(2, 1, figsize=(9, 7), sharex=True)
    ax = axes[0]
    ax.plot(t, z, label="object origin height z [m]")
    ax.plot(t, v, label="vertical velocity [m/s]", alpha=0.7)
    ax.axhspan(c.catch_height_m - c.height_band_m,
               c.catch_height_m + c.height_band_m, color="tab:blue",
               alpha=0.08, label="catch height band")
    ax.axhline(c.catch_height_m, color="tab:blue", lw=0.8, ls="--")
    axes[1].plot(t, np.abs(y_z), color="tab:brown",
                 label="|y_O · z_W| (0: axis horizontal)")
    axes[1].axhline(c.tilt_tolerance, color="k", lw=0.8, ls="--",
                    label="tilt tolerance")
    for p in observation.points:
        style = dict(marker="o", ms=8, color="tab:green",
                     markerfacecolor="tab:green" if p.t_s == used else "none")
        ax.plot(p.t_s, p.p_WO[2], **style)
        axes[1].plot(p.t_s, p.tilt, **style)
        # Catch points lie a few ms apart: only the used one is labelled
        # (the others' v_catch range is in the title).
        if p.t_s == used:
            ax.annotate(f"v_catch {p.v_catch:.2f} m/s", (p.t_s, p.p_WO[2]),
                        textcoords="offset points", xytext=(8, -14),
                        fontsize=8)
    speeds = [p.v_catch for p in observation.points]
    ax.set_title(f"{observation.watched.object}: watched flight, "
                 f"{len(observation.points)} catch point(s)"
                 + (f", v_catch {min(speeds):.2f} … {max(speeds):.2f} m/s"
                    if len(speeds) > 1 else "")
                 + ("" if used is not None else ", none reachable"))
    axes[1].set_xlabel("time [s]")
    for a in axes:
        a.legend(loc="upper right", fontsize=8)
        a.grid(alpha=0.3)
    fig.tight_layout()
    atomic_io.save_figure(fig, path, dpi=90)
    plt.close(fig)
    return Path(path)


def _get(item, name):
    return item[name] if isinstance(item, dict) else getattr(item, name)


def _axis_z(quaternion_wxyz) -> float:
    """z_W component of the object's axis y_O, from its quaternion."""
    w, x, y, z = np.asarray(quaternion_wxyz, float) / np.linalg.norm(
        quaternion_wxyz)
    return 2.0 * (y * z + w * x)
