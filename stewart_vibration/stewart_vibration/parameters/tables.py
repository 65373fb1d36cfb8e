"""Every node's parameters, declared once (pure): one table per node, from which the node declares and validates
them (nodes.node_parameters.declare_table), docs/parameters.md is generated (parameters.docs) and
config/suite_params.yaml is checked (its tests).

Units are SI; "read at start" parameters are read only, the emulator's "read at configure" ones settable while
it is unconfigured.
"""

from __future__ import annotations

from ..emulation.consumer_pace import MAX_WAIT_S
from ..motion.estimate_watch import BLIND_TRAVEL_M, MAX_ESTIMATE_AGE_S
from ..motion.move_goal import MIN_SPEED_SCALE
from ..runtime.sim_clock import REAL_TIME_FACTOR_MAX
from ..vibration.closed_loop import DEFAULT_IMU_AVERAGE_S, DEFAULT_IMU_SILENCE_S
from ..vibration.settings import STREAM_PARAMETERS
from ..vibration.sine_control import DEFAULT_LOOP_GAIN
from .spec import ParameterSpec as P

ROBOT_CONFIG = P("robot_config", "string", "", "robot YAML path ('' = config/robot.yaml)", read_only=True)
PORT_MAX = 65535
RECORDER_QOS_DEPTH = 3000  # 6 s of a 500 Hz stream
MAX_QOS_DEPTH = 1_000_000  # history per recorded topic: beyond this one topic could hold gigabytes in memory
REPLAY_CLOCK_RATE_HZ = 100.0

VIBRATION_PLANNER = (ROBOT_CONFIG,) + tuple(
    P(name, "double", p.default, p.description, "s", p.low, p.high) for name, p in STREAM_PARAMETERS.items()) + (
    P("identification_file", "string", "", "the vibration units' identification (YAML, "
      "vibration.unit_identification): vibrations at its pose and within its frequencies are planned with its "
      "feed-forward; '' = none (uncompensated: the decomposition's legs)"),
    P("closed_loop", "bool", False, "correct the legs' demands while vibrating from the platform IMU (platform/imu) "
      "until the delivered vibration is the planned one, and ramp out when it leaves the abort limits "
      "(DELIVERY_LIMIT); only for a vibration planned with the identification's feed-forward (its response is the "
      "loop's plant estimate)"),
    P("loop_gain", "double", DEFAULT_LOOP_GAIN, "the closed loop's correction per update (of the estimated error)",
      "", 0.05, 1.0),
    P("imu_silence_s", "double", DEFAULT_IMU_SILENCE_S, "the closed loop ramps the vibration out (DELIVERY_LIMIT) "
      "when the newest platform/imu sample it needs is older than this (the loop cannot see what it delivers)", "s",
      0.01, 1.0),
    P("imu_average_s", "double", DEFAULT_IMU_AVERAGE_S, "the IMU's accelerometer averages over this interval before "
      "each sample (its sample period)", "s", 0.0, 0.1),
    P("unit_sensor_latency_s", "double", 0.0, "how old a vibration unit's sensor reading is when reported (its "
      "firmware's control period): removed from the identified unit responses", "s", 0.0, 0.01),)

HARDWARE_EMULATOR = (
    P("robot_config", "string", "", "robot YAML ('' = config/robot.yaml; read at configure)", at_configure=True),
    P("simulation_config", "string", "", "simulation YAML ('' = config/simulation.yaml; read at configure)",
      at_configure=True),
    P("tissue_config", "string", "", "soft-tissue YAML applied to the platform (e.g. tissue.yaml: a name is looked "
      "up in config/; '' = no tissue; read at configure)", at_configure=True),
    P("plant_config", "string", "", "the robot as built: '' or 'ideal' = the drawing (robot.yaml), 'realistic' = "
      "config/plant_realistic.yaml (resonant vibration units, strut servos on encoders, geometry errors, sensor "
      "noise), or a plant YAML path (read at configure)", at_configure=True),
    P("plant_seed", "integer", -1, "seed of the plant's drawn errors; -1 = the plant file's own (read at configure)",
      "", -1, 2**31 - 1, at_configure=True),
    P("autostart", "bool", True, "configure and activate at start (false: wait for the lifecycle transitions)",
      read_only=True),
    P("physics_rate_hz", "double", 2000.0, "physics steps per simulated second (read at configure)", "Hz", 200,
      20000, at_configure=True),
    P("state_rate_hz", "double", 500.0, "joint state / pose rate, sim time (read at configure)", "Hz", 10, 5000,
      at_configure=True),
    P("clock_rate_hz", "double", 100.0, "/clock rate, sim time; every sim-time node wakes for each tick (read at "
      "configure)", "Hz", 10, 5000, at_configure=True),
    P("real_time_factor", "double", 1.0, "sim seconds per wall second; 0 = as fast as possible (live)", "", 0.0,
      REAL_TIME_FACTOR_MAX),
    P("max_consumer_lag_s", "double", 0.1, "above real time (real_time_factor > 1 or 0), or in lockstep, physics "
      "waits while the pose or wrench estimates lag more than this behind sim time (at most "
      f"{MAX_WAIT_S:g} s per wait, then runs on without the late node); at or below real time it waits only in "
      "lockstep; 0 = never (live)", "s", 0.0, 10.0),
    P("lockstep", "bool", False, "wait for late consumers (max_consumer_lag_s) at any real_time_factor, real time "
      "too: a busy machine then slows sim time instead of leaving the estimates behind (live)"),
    P("watchdog_s", "double", 0.5, "a vibration command that ends away from rest is ramped out this long after the "
      "last window (live)", "s", 0.02, 10.0),
    P("vibration_ramp_s", "double", 0.05, "shortest safety ramp-out of the vibration units (watchdog, e-stop, "
      "deactivate); longer where the unit's velocity and acceleration limits need it (live)", "s", 0.005, 0.1),
    P("max_lookahead_s", "double", 30.0, "a vibration window may reach at most this far ahead of now (live)", "s",
      0.1, 600.0),
    P("drive_gain_interval", "integer", 10, "state periods between refreshes of the strut servos' "
      "force-to-acceleration map (read at configure)", "", 1, 1000, at_configure=True),
    P("pace_period_s", "double", 0.02, "wall time between wake-ups of the physics thread at real_time_factor > 0; "
      "the state periods in between run back to back (read at configure)", "s", 0.0, 0.1, at_configure=True),
    P("marker_rate_hz", "double", 10.0, "MarkerArray rate, sim time; 0 = none (read at configure)", "Hz", 0.0, 100.0,
      at_configure=True),
)

KINEMATICS = (
    ROBOT_CONFIG,
    P("trajectory_min_duration_s", "double", 0.5, "shortest point-to-point move", "s", 0.05, 120.0),
    P("trajectory_sample_period_s", "double", 0.02, "spacing of trajectory points", "s", 0.001, 1.0),
    P("speed_scale", "double", 0.5, "fraction of strut_velocity_max used by moves (a goal's own speed_scale "
      "overrides it)", "", MIN_SPEED_SCALE, 1.0),
    P("batch_period_s", "double", 0.02, "queued states are solved at least this often (wall clock; read at start)",
      "s", 0.001, 0.5, read_only=True),
    P("batch_size", "integer", 10, "states solved together as soon as this many have queued (read at start)", "",
      1, 1000, read_only=True),
    P("tissue_config", "string", "", "soft-tissue YAML whose load targets and plan_path are checked against "
      "(strut_force_max_n; a name is looked up in config/; '' = none; read at start)", read_only=True),
    P("guard_force_n", "double", 200.0, "force guard: a move is stopped before the estimated external force exceeds "
      "this (0 = off; example value, not a clinical limit; a change clears a trip)", "N", 0.0, 5000.0),
    P("guard_moment_nm", "double", 15.0, "force guard: likewise for the moment about the platform origin (0 = off; "
      "example value; a change clears a trip)", "N m", 0.0, 500.0),
    P("guard_deceleration_scale", "double", 0.8, "force guard: fraction of strut_acceleration_max a stop may use",
      "", 0.1, 1.0),
    P("guard_blind_travel_m", "double", BLIND_TRAVEL_M, "force guard: moves are slowed so that the struts cover at "
      "most this in the time the external-wrench estimates lag behind the states (largest lag over the last 3 s; "
      "0 = never slowed)", "m", 0.0, 0.05),
    P("guard_max_estimate_age_s", "double", MAX_ESTIMATE_AGE_S, "force guard: a move pauses when the newest "
      "external-wrench estimate is this far behind the newest joint state (the guard would be blind; 0 = off)",
      "s", 0.0, 5.0),
    P("target_rate_hz", "double", 5.0, "move goals taken per second at most, in bursts of as many (wall clock; a "
      "goal while a move is pending or under way is refused anyway; read at start)", "Hz", 0.1, 100.0,
      read_only=True),
    P("goal_position_tolerance_m", "double", 1e-4, "a move goal succeeds when its pose estimate comes this close "
      "to the target (translation)", "m", 1e-7, 0.01),
    P("goal_angle_tolerance_rad", "double", 1e-3, "... and this close in rotation angle", "rad", 1e-6, 0.1),
    P("goal_time_s", "double", 2.0, "a move goal that is not within its tolerance this long after the move's "
      "planned end ends TIMEOUT (robot's clock)", "s", 0.0, 60.0),
    P("pause_timeout_s", "double", 30.0, "a move goal paused for late external-wrench estimates longer than this "
      "ends TIMEOUT, the robot holding (robot's clock)", "s", 1.0, 600.0),
    P("unit_sensor_latency_s", "double", 0.0, "how old a vibration unit's sensor reading is when reported (its "
      "firmware's control period; the units' data sheet): the pose estimate carries it forward (read at start)",
      "s", 0.0, 0.01, read_only=True),
    P("tracker_rate_hz", "double", 60.0, "the external tracker's frame rate (its data sheet; the calibrate action "
      "refuses a window with fewer than half of the frames it promises)", "Hz", 1.0, 1000.0),
    P("tracker_position_noise_m", "double", 2e-5, "the tracker's RMS position noise per axis and frame (its data "
      "sheet; weighs the calibration's residuals; 0 = a noiseless tracker)", "m", 0.0, 1e-3),
    P("tracker_orientation_noise_deg", "double", 0.005, "the tracker's RMS orientation noise per axis and frame "
      "(its data sheet)", "deg", 0.0, 1.0),
)

LEG_FORCE_ESTIMATOR = (
    ROBOT_CONFIG,
    P("rms_window_s", "double", 1.0, "window of the running RMS force error (read at start)", "s", 0.01, 60.0,
      read_only=True),
    P("batch_period_s", "double", 0.02, "queued states are processed at least this often (wall clock; read at "
      "start)", "s", 0.001, 0.5, read_only=True),
    P("batch_size", "integer", 10, "states processed together as soon as this many have queued (read at start)",
      "", 1, 1000, read_only=True),
    P("unit_sensor_latency_s", "double", 0.0, "how old a vibration unit's sensor reading is when reported (its "
      "firmware's control period; the units' data sheet): the sensed unit motion is carried forward by it (read at "
      "start)", "s", 0.0, 0.01, read_only=True),
    P("pistons_follow_struts", "bool", False, "the pistons move with their struts and only each unit's moving mass "
      "vibrates (the robot as built; the units' data sheet): the model takes the pistons' share of the units' "
      "acceleration off; false: the pistons vibrate with the units, as the drawing's emulator lumps them (read at "
      "start)", read_only=True),
)

MCAP_RECORDER = (
    P("output_dir", "string", "", "bag folder of the next file ('' = a new runs/run_<stamp>/ under the working "
      "directory; relative: under the working directory, no '..'; absolute: an existing directory)"),
    P("file_pattern", "string", "run_{stamp}.mcap", "name of the next file, ending in .mcap ({stamp}: local time, "
      "{node}, {index})"),
    P("record_on_start", "bool", True, "open a file at start (else on ~/start)", read_only=True),
    P("topics", "string_array", [""], "topics to record (empty = the suite's)", read_only=True),
    P("qos_depth", "integer", RECORDER_QOS_DEPTH, "history depth of the recording subscriptions (default: 6 s of a "
      "500 Hz stream)", "", 1, MAX_QOS_DEPTH, read_only=True),
    P("chunk_size", "integer", 256 * 1024, "MCAP chunk size of the next file", "bytes", 1024, 64 * 1024 * 1024),
    P("flush_period_s", "double", 0.5, "a chunk is written at least this often (crash safety); next file", "s",
      0.01, 60.0),
    P("discovery_period_s", "double", 0.2, "topic discovery period (read at start)", "s", 0.01, 10.0,
      read_only=True),
)

MCAP_REPLAY = (
    P("path", "string", "", "the .mcap (or run folder) to replay (required)", read_only=True),
    P("rate", "double", 1.0, "replay speed: 2.0 = twice as fast", "", 1e-3, 1e3, read_only=True),
    P("start_offset_s", "double", 0.0, "skip this much of the run", "s", 0.0, 1e9, read_only=True),
    P("loop", "bool", False, "start again at the end", read_only=True),
    P("publish_clock", "bool", False, "publish /clock at clock_rate_hz (the recorded /clock is then not replayed)",
      read_only=True),
    P("clock_rate_hz", "double", REPLAY_CLOCK_RATE_HZ, "wall rate of the published /clock (0 = the recorded /clock's "
      "rate)", "Hz", 0.0, 10_000.0, read_only=True),
    P("topics", "string_array", [""], "topics to replay (empty = all)", read_only=True),
    P("exclude_topics", "string_array", [""], "topics not to replay", read_only=True),
    P("wait_for_subscribers_s", "double", 0.0, "wait up to this long for subscribers before starting", "s", 0.0,
      3600.0, read_only=True),
    P("exit_when_done", "bool", True, "exit after the last message", read_only=True),
)

PLANNING_UI = (
    ROBOT_CONFIG,
    P("host", "string", "127.0.0.1", "address the page is served on (127.0.0.1: this machine only; read at start)",
      read_only=True),
    P("port", "integer", 8080, "TCP port of the page (0 = any free port; read at start)", "", 0, PORT_MAX,
      read_only=True),
    P("frame_rate_hz", "double", 10.0, "live frames sent to the page per second (read at start)", "Hz", 1.0, 30.0,
      read_only=True),
    P("plot_rate_hz", "double", 250.0, "samples per second of the 500 Hz streams sent to the page (decimated; read "
      "at start)", "Hz", 10.0, 500.0, read_only=True),
    P("stale_after_s", "double", 1.0, "data older than this (wall time) is shown greyed as stale", "s", 0.1, 60.0),
    P("command_rate_hz", "double", 5.0, "commands accepted per second from the pages, bursts of twice that (stop "
      "and e-stop are never limited; read at start)", "Hz", 0.1, 100.0, read_only=True),
    P("summary_buffer_s", "double", 60.0, "full-rate streams kept for the run summary (read at start)", "s", 5.0,
      600.0, read_only=True),
)

FOXGLOVE_BRIDGE = (
    P("port", "integer", 8765, "WebSocket port (0 = any free port; read at start)", "", 0, PORT_MAX, read_only=True),
    P("host", "string", "127.0.0.1", "address to listen on (127.0.0.1 = this machine only; read at start)",
      read_only=True),
    P("scene_rate_hz", "double", 30.0, "3D scene rate (wall time; 0 = no scene; read at start)", "Hz", 0.0, 100.0,
      read_only=True),
    P("topics", "string_array", [""], "topics to forward (empty = the suite's)", read_only=True),
    ROBOT_CONFIG,
)

NODE_PARAMETERS: dict[str, tuple[P, ...]] = {
    "hardware_emulator": HARDWARE_EMULATOR,
    "kinematics": KINEMATICS,
    "vibration_planner": VIBRATION_PLANNER,
    "leg_force_estimator": LEG_FORCE_ESTIMATOR,
    "mcap_recorder": MCAP_RECORDER,
    "mcap_replay": MCAP_REPLAY,
    "planning_ui": PLANNING_UI,
    "foxglove_bridge": FOXGLOVE_BRIDGE,
}


def spec_of(node: str, name: str) -> P:
    """The spec of parameter ``name`` of ``node`` (a key of NODE_PARAMETERS); KeyError naming both if there is
    none."""
    for spec in NODE_PARAMETERS[node]:
        if spec.name == name:
            return spec
    raise KeyError(f"{node} has no parameter {name!r}")
