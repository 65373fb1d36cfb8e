"""Running the suite (no rclpy): which nodes make it up (``suite``), their processes and ROS domains
(``processes``), the run's node processes started, supervised and stopped (``bringup``), the scenario
files (``scenario``), the scenario's steps driven through a client (``steps``), the run's output folder
(``run_folders``: runs/run_<stamp>, runs/latest) and how fast the sim clock runs against the wall clock
(``sim_clock``: wall-time margins faster than real time)."""
