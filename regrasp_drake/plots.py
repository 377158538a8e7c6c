"""Pictures of an episode: the sensors over time (the paper's Fig. 11) and the
object's flight."""

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from regrasp_drake.station.catch_state_machine import Phase  # noqa: E402


def plot_episode(result, path: Path) -> Path:
    """Writes a PNG: palm IR 1-3, the nearest approach IR and the bumper over
    time, the phases shaded; and the object's height and axis tilt."""
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
                    else ""))
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
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return Path(path)


def _shade_phases(ax, t, phase):
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
