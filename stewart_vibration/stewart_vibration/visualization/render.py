"""Offline picture of a recorded run in the Foxglove layout's arrangement (matplotlib, Agg; no ROS).

The Foxglove app cannot run on a machine without network access (it is not on any package registry as a
runnable app), so the README's picture is drawn here instead: the 3D scene the bridge publishes
(visualization.scene, the same entities and frames) at one instant of the run, beside the layout's
plots of vib_1..6 and of the leg forces measured (emulator) vs estimated, from the run's MCAP.

    python -m stewart_vibration.visualization.render runs/latest --out docs/foxglove_scene.png [--time T]
"""

from __future__ import annotations

import argparse
import io
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from PIL import Image  # noqa: E402 - matplotlib's own dependency

from ..analysis.report_data import report_data  # noqa: E402
from ..errors import StewartError  # noqa: E402
from ..kinematics.robot_config import load_robot  # noqa: E402
from ..kinematics.rotations import rotation_from_quaternion  # noqa: E402
from ..mcap_log.files import McapFileError  # noqa: E402
from ..mcap_log.reader import open_run  # noqa: E402
from ..messages.joint_trajectory import decode_joint_trajectory  # noqa: E402
from ..messages.stamped_doubles import decode_pose_stamped  # noqa: E402
from ..robot import VIB_NAMES  # noqa: E402
from .scene import Scene, SceneBuilder, vibration_direction_from_window  # noqa: E402

COLORS = plt.get_cmap("tab10").colors  # type: ignore[attr-defined]  # tab10 is a ListedColormap
ZOOM_S = 0.12  # the plots show this much of the run around the chosen instant


def _mesh_cylinder(c, segments: int = 18):
    theta = np.linspace(0, 2 * np.pi, segments + 1)
    ring = np.column_stack([np.cos(theta), np.sin(theta)]) * c.size[0] / 2
    pts = np.stack([np.column_stack([ring, np.full(len(ring), z)]) for z in (-c.size[2] / 2, c.size[2] / 2)])
    return pts @ rotation_from_quaternion(c.orientation).T + c.position  # (2, n, 3) in the entity's frame


def _mesh_sphere(center, diameter: float, n: int = 10):
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, n), np.linspace(0, np.pi, n))
    unit = np.stack([np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v)], axis=-1)
    return unit * diameter / 2 + center


def draw_scene(ax, scene: Scene) -> int:
    """Draw every entity of ``scene`` (base frame) and the base / platform axes into a 3D axes; the
    number of primitives drawn."""
    drawn = 0

    def surface(points, color):
        ax.plot_surface(points[..., 0], points[..., 1], points[..., 2], color=color[:3], shade=True,
                        linewidth=0, antialiased=True)

    for e in scene.entities:
        for c in e.cylinders:
            surface(scene.to_base(e.frame_id, _mesh_cylinder(c)), c.color)
        for s in e.spheres:
            surface(scene.to_base(e.frame_id, _mesh_sphere(s.position, s.diameter)), s.color)
        for line in e.lines:
            p = scene.to_base(e.frame_id, np.vstack([line.points, line.points[:1]]) if line.closed else line.points)
            ax.plot(p[:, 0], p[:, 1], p[:, 2], color=line.color[:3], lw=2.5)
        for a in e.arrows:
            tail = scene.to_base(e.frame_id, a.position)
            d = (scene.to_base(e.frame_id, a.position + a.direction) - tail) * (a.shaft_length + a.head_length)
            ax.quiver(*tail, *d, color=a.color[:3], lw=3, arrow_length_ratio=0.3)
        drawn += len(e.cylinders) + len(e.spheres) + len(e.lines) + len(e.arrows)
    platform = scene.transform("platform")
    for origin, rot in ((np.zeros(3), np.eye(3)),
                        (platform.translation, rotation_from_quaternion(platform.rotation))):
        for k, color in enumerate(("tab:red", "tab:green", "tab:blue")):
            ax.quiver(*origin, *(rot[:, k] * 0.04), color=color, lw=1.2, arrow_length_ratio=0.2)
    return drawn


def _pose_at(reader, topic: str, t_abs_ns: int):
    """(stamp s, position, quaternion) of the recorded pose nearest ``t_abs_ns`` (publish time)."""
    best = min(reader.messages([topic]), key=lambda m: abs(m.publish_time - t_abs_ns))
    stamp, _, position, quaternion = decode_pose_stamped(best.data)
    return stamp, position, quaternion


def _direction_at(reader, topic: str | None, robot, position, quaternion, t_abs_ns: int):
    """Direction of the last vibration window published before ``t_abs_ns``, or None."""
    if topic is None:
        return None
    windows = [m for m in reader.messages([topic]) if m.log_time <= t_abs_ns]
    if not windows:
        return None
    w = decode_joint_trajectory(windows[-1].data)
    index = {n: i for i, n in enumerate(w.names)}
    if w.positions is None or any(n not in index for n in VIB_NAMES):
        return None
    return vibration_direction_from_window(robot, position, quaternion, w.positions[:, [index[n] for n in VIB_NAMES]])


def render_run(path, out, at_s: float | None = None, robot_config=None) -> dict:
    """Write the picture of run ``path`` (a .mcap or its folder) at ``at_s`` (s from the run's first message;
    default: the middle of the vibration, else the end) to ``out``; returns what it drew."""
    reader = open_run(path)
    topics = {t.topic: t for t in reader.topics() if t.message_count}
    pose_topic = next((t for t in topics if t.endswith("ground_truth/platform_pose")), None)
    if pose_topic is None:
        raise StewartError(f"{path}: no ground_truth/platform_pose recorded, nothing to draw")
    robot = load_robot(robot_config)
    data, _signals = report_data(reader, robot)
    t0 = next(reader.messages()).log_time
    window = data.get("vibration_window")
    if at_s is None:
        at_s = (window[0] + window[1]) / 2 if window else float(data["pose_t"][-1])
    t_abs = t0 + int(at_s * 1e9)
    stamp, position, quaternion = _pose_at(reader, pose_topic, t_abs)
    vib_topic = next((t for t in topics if t.endswith("vibration/joint_trajectory")), None)
    direction = None
    if window and window[0] - 0.5 <= at_s <= window[1] + 0.5:
        direction = _direction_at(reader, vib_topic, robot, position, quaternion, t_abs)
    scene = SceneBuilder(robot).scene(position, quaternion, stamp, direction)

    fig = plt.figure(figsize=(13, 7))
    grid = fig.add_gridspec(2, 2, width_ratios=(1.15, 1))
    ax3d = fig.add_subplot(grid[:, 0], projection="3d")
    drawn = draw_scene(ax3d, scene)
    ax3d.set_xlim(-0.13, 0.13)
    ax3d.set_ylim(-0.13, 0.13)
    ax3d.set_zlim(-0.02, 0.22)
    ax3d.set_box_aspect((0.26, 0.26, 0.24))
    ax3d.view_init(elev=22, azim=-58)
    ax3d.set_xlabel("x (m)")
    ax3d.set_ylabel("y (m)")
    ax3d.set_zlabel("z (m)")
    ax3d.set_title(f"3D scene (frame base) at t = {stamp:.3f} s sim", fontsize=9)
    if direction is not None:
        ax3d.text2D(0.02, 0.02, f"red arrow: planned vibration direction {np.round(direction, 3).tolist()}",
                    transform=ax3d.transAxes, fontsize=8)

    zoom = (at_s - ZOOM_S / 2, at_s + ZOOM_S / 2)
    ax_vib, ax_force = fig.add_subplot(grid[0, 1]), fig.add_subplot(grid[1, 1])
    if "vib" in data:
        keep = (data["vib_t"] >= zoom[0]) & (data["vib_t"] <= zoom[1])
        for i in range(6):
            ax_vib.plot(data["vib_t"][keep], data["vib"][keep, i] * 1e6, color=COLORS[i], lw=1, label=f"vib_{i + 1}")
    ax_vib.set_title("legs/joint_states: vib_1..6 (um)", fontsize=9)
    ax_vib.legend(fontsize=7, ncol=6, loc="upper right")
    for t_key, v_key, style in (("force_t", "force", dict(lw=1)), ("est_t", "est", dict(ls="", marker=".", ms=3))):
        if v_key in data:
            keep = np.flatnonzero((data[t_key] >= zoom[0]) & (data[t_key] <= zoom[1]))
            keep = keep[::3] if v_key == "est" else keep  # every third estimate: the lines stay visible
            for i in range(6):
                ax_force.plot(data[t_key][keep], data[v_key][keep, i], color=COLORS[i], **style,
                              label=f"leg_{i + 1}" if v_key == "force" else None)
    ax_force.legend(fontsize=7, ncol=6, loc="upper right")
    ax_force.set_title("leg forces (N): measured (legs/joint_states, lines) vs estimated "
                       "(legs/force_estimate, dots)", fontsize=9)
    ax_force.set_xlabel("time since the run's first message (s)")
    for ax in (ax_vib, ax_force):
        ax.grid(alpha=0.3)
        ax.tick_params(labelsize=8)
    fig.suptitle(f"{Path(reader.path).name}: three of the Foxglove layout's panels, drawn offline with matplotlib "
                 "from the recorded run (not a Foxglove screenshot)", fontsize=10)
    fig.tight_layout()
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    buffer = io.BytesIO()
    fig.savefig(buffer, dpi=100)
    plt.close(fig)
    buffer.seek(0)
    with Image.open(buffer) as image:  # 256-colour palette: a third of the size, same look
        image.convert("RGB").quantize(colors=256, dither=Image.Dither.NONE).save(out, optimize=True)
    return {"out": str(out), "time_s": at_s, "stamp_s": stamp, "primitives": drawn,
            "direction": None if direction is None else direction.tolist()}


def main(argv=None) -> int:
    """``python -m stewart_vibration.visualization.render RUN``: write the run's picture; returns the exit code.

    0 written; 2 (one ``error:`` line) if the run cannot be read or the PNG cannot be written.
    """
    parser = argparse.ArgumentParser(prog="python -m stewart_vibration.visualization.render",
                                     description="picture of a recorded run: the bridge's 3D scene + plots")
    parser.add_argument("run", help="a run's .mcap or its folder (e.g. runs/latest)")
    parser.add_argument("--out", default="scene.png", help="PNG to write")
    parser.add_argument("--time", type=float, default=None,
                        help="instant, s from the run's first message (default: mid-vibration)")
    args = parser.parse_args(argv)
    try:
        result = render_run(args.run, args.out, args.time)
    except (McapFileError, StewartError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {result['out']} (t = {result['time_s']:.3f} s, {result['primitives']} primitives"
          + (f", vibration direction {np.round(result['direction'], 6).tolist()})" if result["direction"] else ")"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
