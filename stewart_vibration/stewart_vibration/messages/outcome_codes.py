"""The suite's one outcome table as pure data: name <-> code of stewart_vibration_interfaces/msg/Outcome.

The pure core reads typed statuses from raw bytes and must name their codes without importing ROS; the table
here is checked against Outcome.msg and against the generated message class by the tests, so the .msg stays
the one place a code is defined."""

from __future__ import annotations

CODES: dict[str, int] = {
    "UNDEFINED": 0, "SUCCEEDED": 1,
    "INVALID_ARGUMENT": 100, "UNKNOWN_FRAME": 101, "UNREACHABLE_POSE": 102, "LIMIT_EXCEEDED": 103,
    "TISSUE_LIMIT": 104, "GUARD_BLOCKED": 105,
    "NOT_READY": 200, "BUSY": 201, "ESTOP_LATCHED": 202, "ROBOT_INACTIVE": 203, "CLOCK_NOT_RUNNING": 204,
    "CLOCK_MISMATCH": 205, "UNITS_NOT_AT_REST": 206, "NOT_RECORDING": 207, "STRUTS_NOT_AT_REST": 208,
    "CANCELED": 300, "GUARD_STOPPED": 301, "ROBOT_REFUSED": 302, "EMERGENCY_STOPPED": 303,
    "UNIT_TRAVEL_STOPPED": 304, "STOPPED_EARLY": 305, "HELD_UP": 306, "PHYSICS_FAULT": 307, "TIMEOUT": 308,
    "SHUTDOWN": 309, "RECORDING_FAILED": 310, "DELIVERY_LIMIT": 311,
    "IDENTIFICATION_REJECTED": 312, "CALIBRATION_REJECTED": 313,
    "INTERNAL_ERROR": 500,
}
NAMES = {code: name for name, code in CODES.items()}


def outcome_name(code: int) -> str:
    """The table's name of ``code`` ("code N" for a code outside the table)."""
    return NAMES.get(code, f"code {code}")
