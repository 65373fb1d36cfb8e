"""Matplotlib (Agg) figures for ``stewart-vibration validate-dynamics``: Fig. 11 / Fig. 12 equivalents."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

COLORS = plt.rcParams["axes.prop_cycle"].by_key()["color"]


def _save(fig, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def forces_figure(result, path: Path) -> Path:
    """Fig. 11 equivalent: six axial forces, MuJoCo (solid), Newton-Euler (dashed), paper model (dotted)."""
    run = result.run
    t = run.time
    fig, ax = plt.subplots(figsize=(10, 5.5))
    for i in range(6):
        ax.plot(t, run.forces[:, i], color=COLORS[i], lw=1.6, label=f"leg {i + 1} MuJoCo")
        ax.plot(t, result.full.model[:, i], color="k", lw=0.8, ls="--")
        ax.plot(t, result.paper.model[:, i], color=COLORS[i], lw=0.9, ls=":")
    ax.plot([], [], color="k", ls="--", label="Newton-Euler (full)")
    ax.plot([], [], color="grey", ls=":", label="paper model (eqs 12-20)")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("axial leg force (N)")
    ax.set_title(f"{result.description}\nfull model worst-leg RMS error {result.full.worst:.2e}, "
                 f"paper model {result.paper.worst:.2e}", fontsize=10)
    ax.legend(fontsize=7, ncol=4, loc="upper center", bbox_to_anchor=(0.5, -0.12))
    ax.grid(alpha=0.3)
    return _save(fig, path)


def legs_figure(result, path: Path) -> Path:
    """Fig. 12 equivalent: per leg, the force about its mean (MuJoCo vs Newton-Euler) and the errors."""
    run = result.run
    t = run.time
    fig, axes = plt.subplots(3, 4, figsize=(14, 8.5))
    for i in range(6):
        ax = axes[i // 2, 2 * (i % 2)]
        mean = run.forces[:, i].mean()
        ax.plot(t, run.forces[:, i] - mean, color=COLORS[i], lw=1.6, label="MuJoCo")
        ax.plot(t, result.full.model[:, i] - mean, color="k", lw=0.8, ls="--", label="Newton-Euler")
        ax.set_title(f"leg {i + 1}: force - {mean:.4f} N", fontsize=9)
        ax.set_ylabel("N")
        ax.legend(fontsize=7)
        err_ax = axes[i // 2, 2 * (i % 2) + 1]
        scale = np.sqrt(np.mean(run.forces[:, i] ** 2))
        err_ax.semilogy(t, np.abs(result.full.model[:, i] - run.forces[:, i]) / scale + 1e-15, color="k",
                        lw=0.8, label=f"full, RMS {result.full.rms_relative[i]:.1e}")
        err_ax.semilogy(t, np.abs(result.paper.model[:, i] - run.forces[:, i]) / scale + 1e-15,
                        color=COLORS[3], lw=0.8, label=f"paper, RMS {result.paper.rms_relative[i]:.1e}")
        err_ax.set_title(f"leg {i + 1}: |error| / RMS force", fontsize=9)
        err_ax.legend(fontsize=7)
        err_ax.set_ylim(1e-12, 1)
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    fig.suptitle(result.description, fontsize=10)
    return _save(fig, path)
