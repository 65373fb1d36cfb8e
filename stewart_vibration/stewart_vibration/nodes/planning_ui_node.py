"""planning_ui node: the surgical planning UI, a browser page over the suite's own interfaces.

Serves the page (stewart_vibration/ui/static) and a WebSocket on ``host``:``port`` (127.0.0.1:8080 by
default; port 0 = any free port) behind a random access token, and logs its URL with the token
(``planning UI at http://127.0.0.1:8080/?token=...``). A taken port: one line, exit code 2.

It uses what any client of the suite uses, nothing private: the kinematics/move_to_pose action (a move is a
goal: its feedback and result, with the outcome code, say how it went; nothing is read from text); calls
kinematics/plan_path (PlanPath: a refusal's code and reason are in the answer), vibration_planner/get_parameters
and describe_parameters (the streaming settings), the vibration_planner/vibrate action (a start is a goal, its
refusal the result's outcome; stop cancels every vibrate goal), hardware_emulator/emergency_stop and /reset
(Trigger); subscribes the vibrate action's feedback (any client's vibration: its plan and what the sensors show
delivered), legs/joint_states, platform/pose_estimate (the controller's pose, FK of the sensed lengths: the page
shows what the controller knows, never the emulator's truth), legs/force_estimate (raw, best effort: a slow page
never holds up a publisher), vibration/status, /diagnostics (the recorder's status names the file it writes in
its ``path`` value).

Commands from the page are checked with the core's own checks before anything is sent (a move with
``kinematics.check_pose``, a start with the planner's settings check and the decomposition's limits) and
rate-limited; stop and the emergency stop are never limited or delayed. Live data go to the page at
``frame_rate_hz`` with the 500 Hz streams decimated to ``plot_rate_hz``; those subscriptions exist only while a
page is open (or a move or vibration it started is followed), so an unwatched UI costs the suite nothing.
After a vibration the page gets its run summary (amplitude, direction error, phases, force error), computed
from the full-rate streams. The page's state and every decision are the pure models of stewart_vibration.ui;
this node converts messages and makes the calls.

The web server runs in a thread of its own (stewart_vibration.ui.server); every rclpy call is made here,
in the executor's thread: commands are queued and run from a 100 Hz steady timer while a page is open (the
EventsExecutor has no guard conditions).
"""

from __future__ import annotations

import secrets
import time
from functools import partial

from action_msgs.srv import CancelGoal
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from rcl_interfaces.srv import DescribeParameters, GetParameters
from rclpy.action import ActionClient
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger

from stewart_vibration_interfaces.action import MoveToPose, Vibrate
from stewart_vibration_interfaces.msg import VibrationUnitsStatus
from stewart_vibration_interfaces.srv import PlanPath

from ..kinematics.robot_config import load_robot
from ..messages.status_values import planner_settings, statuses_from_cdr, vibration_report_from_cdr
from ..parameters.tables import PLANNING_UI
from ..ui import model, page_commands, page_messages
from ..ui.command_queue import CommandInbox, EstopFanOut, ServiceCalls, answering_errors, refusal, trigger_reply
from ..ui.live_streams import DROP, SUBSCRIBE, LiveStreams, StreamWatch
from ..ui.move_follow import FollowedMove
from ..ui.page_messages import PageBackend
from ..ui.planner_settings import PlannerSettings
from ..ui.server import UiServer, bind
from ..ui.suite_status import SuiteStatus
from ..ui.vibration_follow import DeliveredFigures, StartAnswer, VibrationFollow
from ..vibration.settings import STREAM_KEYS, VIBRATION_KEYS
from .diagnostics import OK, Diagnostics, MalformedInputs
from .followed_goal import send_followed_goal
from .message_conversions import JointColumns, pose_from_msg, pose_stamped
from .move_messages import MOVE_ACTION, move_goal, move_result_record
from .node_parameters import declare_table
from .outcomes import outcome_name
from .parameter_answers import ask_parameters
from .run_loop import STATUS_QOS, run_node
from .service_calls import GoalAcceptances
from .vibration_goal import goal_message, plan_record, settings_of_plan

STREAM_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.BEST_EFFORT)
COMMAND_POLL_S = 0.01  # the page's commands are run in the executor's thread within this time
VIBRATE_ACTION = "vibration_planner/vibrate"


class PlanningUiNode(Node):
    """The planning UI's rclpy side: its web server's commands carried out, live frames sent to its pages."""

    def __init__(self):
        super().__init__("planning_ui")
        params = declare_table(self, PLANNING_UI)
        host, port = params["host"], params["port"]
        self.stale_after = params["stale_after_s"]
        self.robot = load_robot(self.get_parameter("robot_config").value or None)
        if host not in ("127.0.0.1", "::1", "localhost"):
            self.get_logger().warning(f"serving on {host}: the page (and the robot) can be reached from other "
                                      "machines by anyone who has the token")
        sock = bind(host, int(port))  # PortInUseError: one line, exit code 2 (run_node)

        self.diagnostics = Diagnostics(self, "planning UI")
        self.malformed = MalformedInputs(self, self.diagnostics)
        # -- the page's state (executor thread; the inbox is filled by the server's thread) --
        self.suite = SuiteStatus(self.diagnostics._name)
        self.live = LiveStreams(params["summary_buffer_s"], params["plot_rate_hz"], JointColumns(),
                                self.malformed.refuse)
        self.vibration = VibrationFollow(self.robot, self.live.buffers, self.suite.events)
        self.move: FollowedMove | None = None  # the move goal this page sent last
        self.planner = PlannerSettings.defaults(self.robot)
        self.inbox = CommandInbox()
        self.calls = ServiceCalls(self.get_logger().error)
        self.watch = StreamWatch(time.monotonic())
        self.streams: list = []  # the 500 Hz subscriptions: only while a page or what it started is watched

        # -- interfaces --
        self.move_client = ActionClient(self, MoveToPose, MOVE_ACTION)
        self.move_acceptances = GoalAcceptances(self, MOVE_ACTION)
        self.create_subscription(VibrationUnitsStatus, "vibration/status", self._on_status, STATUS_QOS, raw=True)
        self.create_subscription(DiagnosticArray, "/diagnostics", self._on_diagnostics, 50, raw=True)
        self.clients_ = {
            "plan_path": self.create_client(PlanPath, "kinematics/plan_path"),
            "get": self.create_client(GetParameters, "vibration_planner/get_parameters"),
            "describe": self.create_client(DescribeParameters, "vibration_planner/describe_parameters"),
            # cancel every vibrate goal, whoever sent it (the action protocol: a zero goal id and stamp)
            "stop": self.create_client(CancelGoal, "vibration_planner/vibrate/_action/cancel_goal"),
            "estop": self.create_client(Trigger, "hardware_emulator/emergency_stop"),
            "reset": self.create_client(Trigger, "hardware_emulator/reset"),
        }
        estop = self.clients_["estop"]
        self.estop = EstopFanOut(estop.srv_name, estop.service_is_ready, lambda: estop.call_async(Trigger.Request()),
                                 estop.remove_pending_request, self.suite.events)
        self.vibrate_client = ActionClient(self, Vibrate, VIBRATE_ACTION)
        self.vibrate_acceptances = GoalAcceptances(self, VIBRATE_ACTION)
        # every vibration's feedback, whoever started it: the plan to follow and what the sensors show delivered
        self.create_subscription(Vibrate.Impl.FeedbackMessage, "vibration_planner/vibrate/_action/feedback",
                                 self._on_vibration_feedback, 10)
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(1.0 / params["frame_rate_hz"], self._frame, clock=steady)
        # rclpy's EventsExecutor has no guard conditions: the queue is polled (an e-stop waits <= 10 ms)
        self.command_timer = self.create_timer(COMMAND_POLL_S, self._run_commands, clock=steady)
        self.command_timer.cancel()  # runs only while a page is open (commands come from pages)
        self.create_timer(2.0, self._slow_tick, clock=steady)
        backend = PageBackend(page_messages.hello(self.robot, self.get_namespace()), self.inbox, self.suite)
        self.server = UiServer(sock, secrets.token_urlsafe(24), backend, command_rate=params["command_rate_hz"],
                               log=self.get_logger().warning)
        self.server.start()
        self.diagnostics.set(OK, "serving", url=f"http://{host}:{self.server.port}/")  # never the token
        self.get_logger().info(f"planning UI at {self.server.url}")

    def shutdown(self) -> None:
        self.server.stop()

    # ==== inputs (executor thread) =====================================================================
    def _on_status(self, data: bytes) -> None:
        report = self.malformed.read("vibration/status", vibration_report_from_cdr, data)
        if report is not None:
            self.live.seen["vibration/status"] = time.monotonic()
            self.vibration.on_status(report)

    def _on_diagnostics(self, data: bytes) -> None:
        statuses, errors = statuses_from_cdr(data)
        for error in errors + self.suite.on_diagnostics(statuses, time.monotonic()):
            self.malformed.refuse("/diagnostics", error)

    def _on_vibration_feedback(self, msg) -> None:
        """A vibration's feedback (this page's goal or another client's: the runner, ros2 action send_goal)."""
        plan = plan_record(msg.feedback.plan)
        self.vibration.on_feedback(plan, settings_of_plan(plan), bytes(msg.goal_id.uuid),
                                   DeliveredFigures.of(msg.feedback))

    # ==== live frames =================================================================================
    def _watch_streams(self) -> None:
        """Run commands only while a page is open; hold the 500 Hz subscriptions while watched (StreamWatch)."""
        following = (self.move is not None and self.move.moving) or self.vibration.following_own_run
        pages = bool(self.server.clients)
        if pages and self.command_timer.is_canceled():
            self.command_timer.reset()
        elif not pages and not self.command_timer.is_canceled():
            self._run_commands()
            self.command_timer.cancel()
        step = self.watch.step(time.monotonic(), pages or following, bool(self.streams))
        if step == SUBSCRIBE:
            raw = [("legs/joint_states", JointState), ("platform/pose_estimate", PoseStamped),
                   ("legs/force_estimate", JointState)]
            self.streams = [self.create_subscription(kind, topic, partial(self.live.receive, topic), STREAM_QOS,
                                                     raw=True) for topic, kind in raw]
        elif step == DROP:
            for sub in self.streams:
                self.destroy_subscription(sub)
            self.streams = []
            self.live.latest_estimate = None

    def _frame(self) -> None:
        self._watch_streams()
        stamps, poses = self.live.drain(time.monotonic())
        if self.move is not None:
            self.move.follow(stamps, poses, time.monotonic())
        self.calls.expire(time.monotonic())
        self._send_estops()  # an e-stop's resend and time-out also when no page is open any more
        if not self.server.clients:  # nobody to show it to
            self.live.take_plots()
            return
        self.server.broadcast(page_messages.frame(self.robot, time.monotonic(), time.time(), self.stale_after,
                                                  self.live, self.move, self.vibration, self.suite, self.planner))

    def _slow_tick(self) -> None:
        if not self.planner.known:  # the planner's settings and declared ranges, for the preview's checks
            ask_parameters(self.clients_["get"], self.clients_["describe"], list(STREAM_KEYS),
                           lambda values: self.planner.got(planner_settings(values)), self.planner.declared,
                           lambda exc: self.malformed.refuse("vibration_planner/get_parameters", exc))
        self.suite.list_report()

    # ==== commands (executor thread) ==================================================================
    def _run_commands(self) -> None:
        self.inbox.run(self._send_estops, self._run_command)

    def _run_command(self, cmd: str, args: dict, reply) -> None:
        answering_errors(lambda: getattr(self, f"_cmd_{cmd}")(args, reply), reply, self.get_logger().error,
                         f"command {cmd} failed")

    def _send_estops(self) -> None:
        self.estop.tick(self.inbox.take_estops())

    def _cmd_check_pose(self, args, reply) -> None:
        reply(page_commands.check_pose_answer(self.robot, args))

    def _cmd_plan_path(self, args, reply) -> None:
        goal = model.pose_from_fields(args)
        request = PlanPath.Request(waypoints=[pose_stamped(goal, self.get_clock().now().to_msg())])  # from the estimate

        def done(response):
            name = outcome_name(response.outcome.code)
            poses = [pose_from_msg(p.pose) for p in response.path.poses] if name == "SUCCEEDED" else []
            reply(page_commands.path_answer(self.robot, name, response.outcome.message, poses))

        self._call("plan_path", request, done, reply)

    def _cmd_move(self, args, reply) -> None:
        target = model.pose_from_fields(args)
        check = model.reachability(self.robot, target)
        if not check["reachable"]:  # refused here; the kinematics node's own reason beside ours (plan_path)
            self._cmd_plan_path(args, lambda answer: reply(page_commands.move_refused(check, answer.get("message"))))
            return
        if not self.move_client.server_is_ready():
            reply(refusal(f"the {MOVE_ACTION} action is not available (is the kinematics node running?)"))
            return
        move = self.move = FollowedMove(target, time.monotonic())
        send_followed_goal(self.move_client, move_goal(target), self.move_acceptances, refused=move.not_taken,
                           feedback=lambda msg: move.progressed(float(msg.feedback.progress)),
                           ended=lambda result: self.suite.events.add(move.ended(move_result_record(result))))
        self.suite.events.add(move.sent_event())
        reply(page_commands.move_sent(MOVE_ACTION, check))

    def _cmd_preview_vibration(self, args, reply) -> None:
        _, settings = self.planner.vibration(self.robot, args)
        reply(page_commands.preview_answer(self.robot, self.live.estimate(time.monotonic()), settings, self.planner))

    def _cmd_start(self, args, reply) -> None:
        _, settings = self.planner.vibration(self.robot, args)
        pose = self.live.estimate(time.monotonic())
        preview, refused = page_commands.start_check(self.robot, pose, settings, self.planner, self.move,
                                                     time.monotonic())
        if refused is None and not self.vibrate_client.server_is_ready():
            refused = refusal(f"the {VIBRATE_ACTION} action is not available (is the vibration planner running?)")
        if refused is not None:
            reply(refused)
            return
        start = StartAnswer(reply, preview)

        def on_feedback(msg) -> None:  # the first feedback carries the plan: the vibration started
            if not start.answered:  # the run itself is followed from the feedback topic (every goal's)
                self.suite.events.add(start.started(plan_record(msg.feedback.plan)))

        send_followed_goal(self.vibrate_client, goal_message({k: settings[k] for k in VIBRATION_KEYS}),
                           self.vibrate_acceptances, feedback=on_feedback, refused=start.not_accepted,
                           taken=lambda handle: self.vibration.sent(bytes(handle.goal_id.uuid)),
                           ended=lambda result: self.suite.events.add(
                               start.ended(outcome_name(result.outcome.code), result.outcome.message)))

    def _cmd_stop(self, args, reply) -> None:
        """Cancel every vibration (the units ramp out), whichever client started it."""
        self._call("stop", CancelGoal.Request(), lambda response: reply(page_commands.cancel_answer(
            response.return_code == CancelGoal.Response.ERROR_NONE, len(response.goals_canceling))), reply)

    def _cmd_reset(self, args, reply) -> None:
        refused_by = self.clients_["reset"].srv_name.split("/")[-2]
        self._call("reset", Trigger.Request(), lambda response: reply(trigger_reply(response, refused_by)), reply)

    # ==== service plumbing ============================================================================
    def _call(self, name: str, request, done, reply) -> None:
        client = self.clients_[name]
        self.calls.call(client.srv_name, client.service_is_ready(), lambda: client.call_async(request), done, reply,
                        time.monotonic())


def main(args=None) -> int:
    """Run the planning_ui node until SIGINT / SIGTERM; returns the exit code (2: it cannot start)."""
    return run_node(PlanningUiNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
