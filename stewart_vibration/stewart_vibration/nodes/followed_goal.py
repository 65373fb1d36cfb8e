"""An action goal sent and followed through callbacks (no waiting: for a node whose executor must not block)."""

from __future__ import annotations

from collections.abc import Callable

from .service_calls import GoalAcceptances, send_goal_recovering_async


def send_followed_goal(client, goal, acceptances: GoalAcceptances, *, feedback: Callable, ended: Callable,
                       refused: Callable[[], None], taken: Callable | None = None) -> None:
    """Send ``goal`` through ``client`` (rclpy ActionClient, server ready; send_goal_recovering_async):
    ``feedback(msg)`` for each feedback message, ``taken(handle)`` once the server took it, ``ended(result)``
    with its result (not called when rclpy gives none), ``refused()`` when it was not taken or sending failed."""
    def on_result(future) -> None:
        answer = future.result()
        if answer is not None:
            ended(answer.result)

    def on_goal(future) -> None:
        if future.exception() is not None or not future.result().accepted:
            refused()
            return
        if taken is not None:
            taken(future.result())
        future.result().get_result_async().add_done_callback(on_result)

    send_goal_recovering_async(client, goal, acceptances, feedback_callback=feedback).add_done_callback(on_goal)
