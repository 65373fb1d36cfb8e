"""PNG plots of a run (matplotlib's Agg canvas, without pyplot): one figure per subject, only for data present.

Each figure is a function of the run's data and summary that writes its PNG and returns the names it wrote
(``FIGURES``, in the report's order): the report may draw them in worker processes (``plot_pool``).
"""

from __future__ import annotations

from pathlib import Path
from typing import cast

import matplotlib
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

COLORS = matplotlib.colormaps["tab10"].colors  # type: ignore[attr-defined]  # tab10 is a ListedColormap
PLOT_BINS = 600  # a whole-run line is drawn as this many min/max pairs at most: about one per pixel column of the
# widest axes (half a 13 in figure at DPI); more strokes than pixel columns cost drawing time and draw the same band
PATH_POINTS = 20_000  # samples of the 3D vibration path drawn at most
DPI = 110  # dots per inch of the PNGs


def envelope(t, y, bins: int = PLOT_BINS) -> tuple[np.ndarray, np.ndarray]:
    """(t, y) [n] reduced for a line plot: with more than 2 ``bins`` samples, each of ``bins`` equal runs of
    samples becomes a vertical stroke from its min to its max at its middle time (every peak stays drawn, and an
    hour of 500 Hz samples does not cost a figure millions of points); fewer samples are returned as they are.
    Non-finite samples are left out of the min and max."""
    t, y = np.asarray(t, dtype=float), np.asarray(y, dtype=float)
    if t.size <= 2 * bins:
        return t, y
    starts = np.linspace(0, t.size, bins + 1).astype(int)[:-1]
    finite = np.where(np.isfinite(y), y, np.nan)
    with np.errstate(invalid="ignore"):
        low = np.fmin.reduceat(finite, starts)
        high = np.fmax.reduceat(finite, starts)
    middle = t[starts + np.diff(np.append(starts, t.size)) // 2]
    return np.repeat(middle, 2), np.column_stack([low, high]).ravel()


def _line(ax, t, y, **style) -> None:
    """``ax.plot`` of a whole-run series through its ``envelope``."""
    ax.plot(*envelope(t, y), **style)


def _figure(**layout) -> Figure:
    """A figure on an Agg canvas (no pyplot: nothing registers or holds it); ``layout``: Figure's arguments."""
    fig = Figure(**layout)
    FigureCanvasAgg(fig)
    return fig


def _legs_grid(title: str):
    fig = _figure(figsize=(11, 8))
    axes = fig.subplots(3, 2, sharex=True)
    fig.suptitle(title)
    return fig, axes.ravel()


def _save(fig, out: Path, name: str) -> list[str]:
    """Lay ``fig`` out, write it as ``out``/``name``; returns [name]."""
    fig.tight_layout()
    # laid out once: without this savefig draws the figure twice, the first time only to run a layout engine
    fig.set_layout_engine(None)
    fig.savefig(out / name, dpi=DPI)
    return [name]


def _legs_in_mm(title: str, t, values, titles: list[str], ylabel: str):
    """The 3 x 2 grid of one whole-run series per leg: ``values`` [n, 6] (m) drawn in mm over ``t`` [n] (s)."""
    fig, axes = _legs_grid(title)
    for i, ax in enumerate(axes):
        _line(ax, t, values[:, i] * 1e3, color=COLORS[i], lw=0.8)
        ax.set_title(titles[i])
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
    for ax in axes[-2:]:
        ax.set_xlabel("time (s)")
    return fig


def leg_lengths(data: dict, summary: dict, out: Path) -> list[str]:
    """leg_lengths.png: each leg's length over the run (mm)."""
    if "leg_lengths" not in data:
        return []
    fig = _legs_in_mm("Leg lengths (strut, from legs/joint_states)", data["leg_t"], data["leg_lengths"],
                      [f"leg_{i + 1}" for i in range(6)], "length (mm)")
    return _save(fig, out, "leg_lengths.png")


def vibration(data: dict, summary: dict, out: Path) -> list[str]:
    """vibration.png: each vibration unit's displacement over the run (mm), its fitted amplitude in the title."""
    if "vib" not in data:
        return []
    vib = [summary.get("vibration", {}).get(f"vib_{i + 1}", {}) for i in range(6)]
    titles = [f"vib_{i + 1}: {v.get('amplitude_m', 0) * 1e3:.3f} mm at {v.get('frequency_hz', 0):.3f} Hz"
              for i, v in enumerate(vib)]
    fig = _legs_in_mm("Vibration unit displacement per leg (vib_*)", data["vib_t"], data["vib"], titles,
                      "displacement (mm)")
    return _save(fig, out, "vibration.png")


def platform(data: dict, summary: dict, out: Path) -> list[str]:
    """platform.png: the platform's position about its mean over the run (mm), and its vibration path (um, 3D)
    with the fitted amplitude and direction."""
    if "pose_xyz" not in data:
        return []
    fig = _figure(figsize=(13, 6))
    mean = data["pose_mean"]
    dev = (data["pose_xyz"] - mean) * 1e3
    for k, name in enumerate("xyz"):
        ax = fig.add_subplot(3, 2, 2 * k + 1)
        _line(ax, data["pose_t"], dev[:, k], color=COLORS[k], lw=0.8)
        ax.set_ylabel(f"{name} (mm)\nmean {mean[k] * 1e3:.2f}")
        ax.grid(alpha=0.3)
        if k == 0:
            ax.set_title("Platform position about its mean (ground_truth/platform_pose)")
    ax.set_xlabel("time (s)")
    ax3 = fig.add_subplot(1, 2, 2, projection="3d")
    window = data.get("analysed_window")
    steady = data.get("window", {})
    if window and steady.get("pose") is not None and len(steady["pose"]):  # the vibration, in um, about its mean
        path = (steady["pose"] - steady["pose"].mean(axis=0)) * 1e6
        path = path[::max(1, path.shape[0] // PATH_POINTS)]  # a back-and-forth line: a stride keeps its shape
        ax3.plot(path[:, 0], path[:, 1], path[:, 2], lw=0.8, color="gray")
        p = summary.get("platform", {})
        if p:
            d = np.array(p["vibration_direction"]) * p["vibration_amplitude_m"] * 1e6
            ax3.quiver(0, 0, 0, *d, color="red", lw=2)
            ax3.set_title(f"Vibration path {window[0]:.2f}-{window[1]:.2f} s (um, equal axes)\n"
                          f"red: amplitude {p['vibration_amplitude_m'] * 1e6:.2f} um along ["
                          + ", ".join(f"{x:.3f}" for x in p["vibration_direction"]) + "] (base frame)",
                          fontsize=10)
        r = max(float(np.abs(path).max()), 1e-6)
        for setter in (ax3.set_xlim, ax3.set_ylim, ax3.set_zlim):
            setter(-r, r)
    else:
        ax3.set_title("no vibration in this run", fontsize=10)
    ax3.set_xlabel("x (um)")
    ax3.set_ylabel("y (um)")
    ax3.set_zlabel("z (um)")
    return _save(fig, out, "platform.png")


def forces(data: dict, summary: dict, out: Path) -> list[str]:
    """forces.png: each leg's measured and estimated axial force over the run (N)."""
    if "force" not in data and "est" not in data:
        return []
    fig, axes = _legs_grid("Leg axial force: measured (legs/joint_states) vs estimated (legs/force_estimate)")
    for i, ax in enumerate(axes):
        if "force" in data:
            _line(ax, data["force_t"], data["force"][:, i], color="black", lw=1.0, label="measured")
        if "est" in data:
            _line(ax, data["est_t"], data["est"][:, i], color="tab:orange", lw=1.0, ls="--", label="estimated")
        ax.set_title(f"leg_{i + 1}")
        ax.set_ylabel("force (N)")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right")
    for ax in axes[-2:]:
        ax.set_xlabel("time (s)")
    return _save(fig, out, "forces.png")


def forces_vibration(data: dict, summary: dict, out: Path) -> list[str]:
    """forces_vibration.png: 0.1 s of each leg's measured and estimated force in the middle of the steady
    vibration (N), every sample."""
    window, steady = data.get("analysed_window"), data.get("window", {})
    if not (window and "force" in data and "est" in data and "force" in steady):
        return []
    mid = 0.5 * (window[0] + window[1])
    fig, axes = _legs_grid(f"Leg axial force during the vibration, {mid:.2f}-{mid + 0.1:.2f} s: "
                           "measured (black) vs estimated (orange dashed)")
    ms = (steady["force_t"] >= mid) & (steady["force_t"] <= mid + 0.1)
    es = (steady["est_t"] >= mid) & (steady["est_t"] <= mid + 0.1)
    for i, ax in enumerate(axes):
        ax.plot(steady["force_t"][ms], steady["force"][ms, i], color="black", lw=1.2, label="measured")
        ax.plot(steady["est_t"][es], steady["est"][es, i], color="tab:orange", lw=1.2, ls="--", label="estimated")
        ax.set_title(f"leg_{i + 1}")
        ax.set_ylabel("force (N)")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right")
    for ax in axes[-2:]:
        ax.set_xlabel("time (s)")
    return _save(fig, out, "forces_vibration.png")


def events(data: dict, summary: dict, out: Path) -> list[str]:
    """events.png: the first 20 events on the run's time axis, coloured by level."""
    found = data.get("events", [])
    if not found:
        return []
    fig = _figure(figsize=(11, 1.2 + 0.35 * min(len(found), 20)))
    ax = fig.subplots()
    levels = {0: "tab:green", 1: "tab:orange", 2: "tab:red", 3: "gray"}
    for k, e in enumerate(found[:20]):
        fallback = "tab:red" if e["level"] >= 40 else "tab:orange" if e["level"] >= 30 else "tab:blue"
        color = levels.get(e["level"], fallback)
        ax.plot([e["t_s"]], [k], "o", color=color)
        ax.annotate(f"{e['source']}: {e['text']}", (e["t_s"], k), xytext=(6, -3), textcoords="offset points",
                    fontsize=8)
    ax.set_yticks([])
    ax.margins(x=0.3, y=0.4)
    ax.invert_yaxis()
    ax.set_xlabel("time (s)")
    ax.set_title("Events (/diagnostics, /rosout warnings and start/stop)")
    ax.grid(alpha=0.3, axis="x")
    return _save(fig, out, "events.png")


def tissue_wrench(data: dict, summary: dict, out: Path) -> list[str]:
    """tissue_wrench.png, with an applied tissue wrench: the wrench the emulator applied vs the estimator's
    external wrench, force and moment components and the error magnitudes; the force guard's trips as vertical
    lines."""
    if "wrench_applied" not in data:
        return []
    fig = _figure(figsize=(13, 8))
    axes = fig.subplots(3, 2, sharex=True)
    fig.suptitle("Soft tissue: applied (ground_truth/tissue_wrench, solid) vs estimated "
                 "(platform/external_wrench_estimate, dashed); base frame, moment about the platform origin")
    ta, wa = data["wrench_applied_t"], data["wrench_applied"]
    te, we = data.get("wrench_estimated_t"), data.get("wrench_estimated")
    for col, (what, unit, first) in enumerate((("force", "N", 0), ("moment", "N m", 3))):
        ax = axes[0, col]
        for k, name in enumerate("xyz"):
            _line(ax, ta, wa[:, first + k], color=COLORS[k], lw=1.0, label=f"{name} applied")
            if we is not None:
                _line(ax, te, we[:, first + k], color=COLORS[k], lw=1.0, ls="--", label=f"{name} estimated")
        ax.set_title(f"{what} components")
        ax.set_ylabel(f"{what} ({unit})")
        ax.legend(loc="upper right", fontsize=7, ncol=2)
        ax = axes[1, col]
        _line(ax, ta, np.linalg.norm(wa[:, first:first + 3], axis=1), color="black", lw=1.0, label="|applied|")
        if we is not None:
            _line(ax, te, np.linalg.norm(we[:, first:first + 3], axis=1), color="tab:orange", lw=1.0, ls="--",
                    label="|estimated|")
        ax.set_ylabel(f"|{what}| ({unit})")
        ax.legend(loc="best", fontsize=7)
        ax = axes[2, col]
        if we is not None:
            # te: set with we (report_data.report_data)
            common, ia, ie = np.intersect1d(np.round(ta, 6), np.round(cast(np.ndarray, te), 6), return_indices=True)
            err = np.linalg.norm(we[ie, first:first + 3] - wa[ia, first:first + 3], axis=1)
            _line(ax, common, err, color="tab:red", lw=0.8)
        ax.set_ylabel(f"|error| ({unit})")
        ax.set_xlabel("time (s)")
    for trip in data.get("guard_trips", []):
        for ax in axes.ravel():
            ax.axvline(trip["t_s"], color="tab:red", lw=1.0, ls=":")
        axes[0, 0].annotate(f"guard stop ({trip.get('trip_limit', '')})", (trip["t_s"], axes[0, 0].get_ylim()[0]),
                            xytext=(4, 4), textcoords="offset points", fontsize=8, color="tab:red")
        if trip.get("trip_limit") == "force":
            axes[1, 0].axhline(float(trip["force_limit_n"]), color="tab:red", lw=0.8, ls=":")
    for ax in axes.ravel():
        ax.grid(alpha=0.3)
    return _save(fig, out, "tissue_wrench.png")


FIGURES = (leg_lengths, vibration, platform, forces, forces_vibration, tissue_wrench, events)  # the report's order
TITLED = (vibration, platform)  # the figures that read the summary (the others are drawn from the data alone)


def plot_all(data: dict, summary: dict, out: Path) -> list[str]:
    """Write the PNGs into ``out`` (``FIGURES`` one after the other); returns their file names.

    One figure per subject, only for the data present (lengths and displacements plotted in mm, times
    in s from the first message).

    Args:
        data: the run's data (``report_data.report_data``): whole-run series as envelopes, the steady
            vibration's samples in "window".
        summary: the run's summary (``run_report.summarize``), for the figures' titles.
        out: an existing directory to write into.

    Returns:
        The file names of the PNGs written, in order.
    """
    return [name for figure in FIGURES for name in figure(data, summary, out)]
