"""Running the suite (no rclpy): which nodes make it up (``suite``), their processes and ROS domains
(``processes``), the scenario files (``scenario``) and the scenario's steps driven through a client
(``steps``)."""
