"""Matplotlib (Agg) figures for ``stewart-vibration paper``: Fig. 7/8/9 equivalents and the naive-sum comparison."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

UM = 1e6
COLORS = plt.rcParams["axes.prop_cycle"].by_key()["color"]


def _save(fig, path: Path) -> Path:
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def fig7(cases: dict, path: Path) -> Path:
    """3-D platform-origin trajectories (exact FK solid, J^-1 dashed) of the three Fig. 7 leg sets."""
    fig = plt.figure(figsize=(16, 5.8))
    for col, (key, case) in enumerate(cases.items()):
        res = case["result"]
        cls = res.classification
        ax = fig.add_subplot(1, 3, col + 1, projection="3d")
        ex, lin = res.exact[:, :3] * UM, res.linear[:, :3] * UM
        ax.plot(*ex.T, color=COLORS[0], lw=1.4, label="exact (FK)")
        ax.plot(*lin.T, color=COLORS[1], lw=1.0, ls="--", label="linear (J$^{-1}$)")
        centre = ex.mean(axis=0)
        arrow = cls.principal_direction * cls.translation_amplitude * UM
        ax.plot(*np.stack([centre - arrow, centre + arrow]).T, color="k", lw=0.8, ls=":", label="principal axis")
        ax.set_xlabel("x (µm)")
        ax.set_ylabel("y (µm)")
        ax.set_zlabel("z (µm)", labelpad=6)
        span = np.ptp(np.vstack([ex, lin]), axis=0)
        ax.set_box_aspect(np.maximum(span, 0.3 * span.max()))  # true shape; flat axes shown >= 30 % for labels
        ax.tick_params(labelsize=7)
        legs = case["legs"]
        kind = cls.kind.upper() + (" + ROCKING (screw)" if cls.kind == "line" and cls.rotational_ratio > 0.01 else "")
        detail = {"7a": f"f = {', '.join(f'{f:g}' for f in legs[:, 1])} Hz, A = {legs[0, 0] * UM:g} µm",
                  "7b": f"phase of leg i = (i−1)·60°, f = {legs[0, 1]:g} Hz, A = {legs[0, 0] * UM:g} µm",
                  "7c": f"A = {', '.join(f'{a * UM:g}' for a in legs[:, 0])} µm, f = {legs[0, 1]:g} Hz"}[key]
        ax.set_title(f"Fig. {key} equivalent: {case['label']}\n{detail}\n"
                     f"→ {kind}, off-axis {cls.off_axis_ratio:.3g}, "
                     f"rotation {cls.rotation_amplitude * 1e3:.3g} mrad", fontsize=9)
        if col == 0:
            ax.legend(fontsize=7, loc="upper left")
    fig.suptitle("Superposition of six leg vibrations at the paper's pose: platform-origin displacement "
                 "(base frame)", fontsize=11)
    fig.subplots_adjust(left=0.02, right=0.97, top=0.80, bottom=0.04, wspace=0.12)
    return _save(fig, path)


def _length_unit(values_m) -> tuple[float, str]:
    """(scale, label) so that the peak of ``values_m`` reads between ~0.1 and ~1000."""
    peak = float(np.abs(values_m).max())
    for scale, label in ((1e12, "pm"), (1e9, "nm"), (1e6, "µm")):
        if peak * scale < 1000:
            return scale, label
    return 1e3, "mm"


def _title(case: dict) -> str:
    plan = case["plan"]
    return (f"A = {plan.amplitude * UM:.4g} µm, f = {plan.frequency:.4g} Hz (ω = {plan.angular_frequency:.4g} rad/s), "
            f"phase {plan.phase:.4g} rad, along the tibia axis")


def fig8(case: dict, name: str, path: Path) -> Path:
    """Six leg length changes, exact IK vs linear k_i delta, and their difference vs the 2nd-order prediction."""
    plan = case["plan"]
    t = plan.times
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(13, 7.5), sharex=True)
    scale, unit = _length_unit(case["difference"])
    for i in range(6):
        top.plot(t, plan.exact_signals[:, i] * UM, color=COLORS[i], lw=1.6, label=f"leg {i + 1} exact (IK)")
        top.plot(t[::6], plan.linear_signals[::6, i] * UM, color=COLORS[i], ls="none", marker="o", ms=3,
                 label=f"leg {i + 1} linear k·δ")
        bottom.plot(t, case["difference"][:, i] * scale, color=COLORS[i], lw=1.6, label=f"leg {i + 1}")
        bottom.plot(t, case["predicted_difference"][:, i] * scale, color="k", lw=0.7, ls=":")
    bottom.plot([], [], color="k", lw=0.7, ls=":", label="(1−k²)δ²/(2l)")
    top.set_ylabel("leg length change Δl (µm)")
    top.set_title(f"Fig. 8 equivalent ({name}): {_title(case)}", fontsize=10)
    top.legend(fontsize=7, ncol=1, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    top.grid(alpha=0.3)
    bottom.set_ylabel(f"exact − linear ({unit})")
    bottom.set_xlabel("time t (s)")
    bottom.set_title(f"Difference = second-order term; residual vs prediction "
                     f"{case['second_order_residual_ratio']:.2g} of its peak", fontsize=10)
    bottom.legend(fontsize=7, ncol=1, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    bottom.grid(alpha=0.3)
    fig.tight_layout()
    return _save(fig, path)


def fig9(case: dict, name: str, path: Path, leg: int = 1) -> Path:
    """One leg: exact vs linear, their difference, and the FFT of the exact signal."""
    plan = case["plan"]
    i = leg - 1
    t = plan.times
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.6))
    ax = axes[0]
    ax.plot(t, plan.exact_signals[:, i] * UM, lw=1.8, label="exact (IK)")
    ax.plot(t, plan.linear_signals[:, i] * UM, ls="--", lw=1.2, label=f"linear k·δ, k = {plan.gains[i]:.4f}")
    ax.set_xlabel("time t (s)")
    ax.set_ylabel(f"leg {leg} length change (µm)")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    ax = axes[1]
    scale, unit = _length_unit(case["difference"][:, i])
    ax.plot(t, case["difference"][:, i] * scale, lw=1.8, label="exact − linear")
    ax.plot(t, case["predicted_difference"][:, i] * scale, "k:", lw=1.2, label="(1−k²)δ²/(2l)")
    ax.set_xlabel("time t (s)")
    ax.set_ylabel(f"exact − linear ({unit})")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    ax = axes[2]
    amps = np.array([case["fft_dc_m"][i], case["fft_fundamental_m"][i], case["fft_second_harmonic_m"][i]])
    labels = ["DC", "f", "2f"]
    bars = ax.bar(labels, amps, color=COLORS[:3])
    ax.set_yscale("log")
    ax.set_ylabel("FFT amplitude (m, log)")
    for bar, value in zip(bars, amps):
        ax.annotate(f"{value:.3g} m", (bar.get_x() + bar.get_width() / 2, value), ha="center", va="bottom",
                    fontsize=8)
    ratio = case["fft_second_harmonic_m"][i] / case["fft_fundamental_m"][i]
    ax.set_title(f"2f/f = {ratio:.3g} (predicted {case['predicted_second_harmonic_ratio'][i]:.3g})", fontsize=9)
    fig.suptitle(f"Fig. 9 equivalent ({name}), leg {leg}: {_title(case)}", fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


def fig_naive(comparison: dict, path: Path) -> Path:
    """The paper's naive sum_i n_i dl_i vs J^-1 dl: direction and length errors."""
    fig = plt.figure(figsize=(17, 5.5))
    first = next(iter(comparison.values()))
    res = first["result"]
    # the plane spanned by the force line u and the naive direction: true lengths and angles in 2-D
    u = first["direction_base"]
    perp = first["naive_direction_base"] - (first["naive_direction_base"] @ u) * u
    perp = perp / np.linalg.norm(perp)
    ax = fig.add_subplot(1, 3, 1)
    for traj, style, label in ((res.linear[:, :3], "-", "J$^{-1}$ dl (correct): along the force line u"),
                               (res.naive, "-", "paper: Σ n$_i$ dl$_i$ (wrong)")):
        ax.plot(traj @ u * UM, traj @ perp * UM, ls=style, lw=2.2, label=label)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("along the force line u (µm)")
    ax.set_ylabel("perpendicular, in the plane of u and the naive sum (µm)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper left")
    ax.set_title(f"Tibia-axis vibration, A = 1 µm, paper pose:\nnaive sum is "
                 f"{first['length_ratio']:.2f}× too long, {np.degrees(first['angle_error_rad']):.1f}° off", fontsize=9)
    labels = list(comparison)
    x = np.arange(len(labels))
    ax = fig.add_subplot(1, 3, 2)
    ax.bar(x, [comparison[k]["length_ratio"] for k in labels], color=COLORS[1])
    ax.axhline(1.0, color="k", lw=0.8, ls=":")
    ax.set_xticks(x, [k.replace(" (", "\n(") for k in labels], fontsize=8)
    ax.set_ylabel("length ratio |naive| / |J$^{-1}$ dl|")
    ax.set_title("Amplitude error of the naive sum (1 = correct)", fontsize=9)
    ax = fig.add_subplot(1, 3, 3)
    ax.bar(x, [np.degrees(comparison[k]["angle_error_rad"]) for k in labels], color=COLORS[3])
    ax.set_xticks(x, [k.replace(" (", "\n(") for k in labels], fontsize=8)
    ax.set_ylabel("direction error (deg)")
    ax.set_title("Direction error of the naive sum (0 = correct)", fontsize=9)
    fig.suptitle("Paper's superposition (Σ s$_i$·Δl$_i$) vs the Jacobian inverse, legs decomposed for a line "
                 "along each direction", fontsize=10)
    fig.subplots_adjust(left=0.05, right=0.98, top=0.84, bottom=0.14, wspace=0.3)
    return _save(fig, path)
