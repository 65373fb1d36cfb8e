"""Drive kinematics' calibrate action from a command line (``stewart-vibration calibrate``): send the goal
once (recovering a lost answer from the action's status), report its feedback, wait for its result; Ctrl-C
cancels it (the running move stops, nothing is written) and waits for that end."""

from __future__ import annotations

import time
from collections.abc import Callable

from stewart_vibration_interfaces.action import Calibrate

from .outcomes import outcome_name
from .service_calls import GoalAcceptances, send_goal_recovering_async

CANCEL_WAIT_S = 60.0  # wall s for a cancelled calibration to stop its move and end


def calibrate(namespace: str, goal: Calibrate.Goal, server_wait_s: float, timeout_s: float,
              progress: Callable[[str], None]) -> tuple[str, Calibrate.Result | None]:
    """(outcome name, result) of one calibration; ("NOT_READY", None) when the action is not served within
    ``server_wait_s`` (a NOT_READY answer is asked again until then: a suite still starting), ("TIMEOUT",
    None) without a result within ``timeout_s`` (both wall s; the goal is then cancelled), ("CANCELED", result
    or None) after Ctrl-C. Runs rclpy in this process (init and shutdown)."""
    import rclpy
    from rclpy.action import ActionClient
    from rclpy.signals import SignalHandlerOptions

    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node(f"calibrate_{int(time.time() * 1000) % 100000}", namespace=namespace)
    name = "kinematics/calibrate"

    def spin_until(done: Callable[[], bool], seconds: float) -> bool:
        end = time.monotonic() + seconds
        while not done() and time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.05)
        return done()

    def on_feedback(msg) -> None:
        f = msg.feedback
        if f.stage == "planned":
            progress(f"planned {f.poses} poses: condition number {f.condition_number:.1f}, predicted parameter "
                     f"std up to {f.predicted_std_max_m * 1e6:.2f} um")
        elif f.stage == "moving" or f.stage == "identifying":
            progress(f"{f.stage} {f'pose {f.pose}/{f.poses}' if f.stage == 'moving' else ''}".rstrip())

    try:
        client = ActionClient(node, Calibrate, name)
        acceptances = GoalAcceptances(node, name)
        ready_by = time.monotonic() + server_wait_s
        if not spin_until(client.server_is_ready, server_wait_s):
            return "NOT_READY", None
        while True:
            sent = send_goal_recovering_async(client, goal, acceptances, on_feedback)
            if not spin_until(sent.done, 30.0) or not sent.result().accepted:
                return "NOT_READY", None
            handle = sent.result()
            answer = handle.get_result_async()
            try:
                if not spin_until(answer.done, timeout_s):
                    progress(f"no result within {timeout_s:g} s: cancelling")
                    timed_out = True
                    break
                result = answer.result().result
                name = outcome_name(result.outcome.code)
                if name != "NOT_READY" or time.monotonic() >= ready_by:
                    return name, result
                # the suite is still starting (kinematics has no joint state yet): asked again within --wait
                spin_until(lambda: False, 0.5)
            except KeyboardInterrupt:
                progress("interrupted: cancelling the calibration (the running move stops, nothing is written)")
                timed_out = False
                break
        handle.cancel_goal_async()
        spin_until(answer.done, CANCEL_WAIT_S)
        result = answer.result().result if answer.done() else None
        return ("TIMEOUT" if timed_out else "CANCELED"), result
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
