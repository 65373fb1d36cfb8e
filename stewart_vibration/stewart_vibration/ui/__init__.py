"""The surgical planning UI: a browser page served by the ``planning_ui`` node.

- ``model``: the page's model and its server-side checks (pure: numpy and the core, no rclpy, no web
  server): pose entry in mm/deg -> reachability, path margins, vibration preview,
  rate limiting, decimation.
- ``server``: the HTTP + WebSocket server (asyncio + ``websockets``; no rclpy): token, static page,
  commands in, live frames out.
- the page's state, pure and stepped by the node: ``live_streams`` (the 500 Hz streams: buffers, plot rows,
  when to subscribe), ``move_follow`` (a move until it settles), ``vibration_follow`` (any client's vibration,
  its summary, the page's start), ``suite_status`` (nodes' statuses, events, the recorder's file),
  ``planner_settings``, ``command_queue`` (commands, service calls, the e-stop's fan-out), ``page_commands``
  (the commands' answers) and ``page_messages`` (hello, frames, the server's backend).
- ``static/``: the page (plain HTML/JS/CSS, plots drawn on <canvas>; no CDN, works offline).

The rclpy side (topics, services, parameters) is ``stewart_vibration.nodes.planning_ui_node``.
"""

from pathlib import Path

STATIC_DIR = Path(__file__).resolve().parent / "static"

__all__ = ["STATIC_DIR"]
