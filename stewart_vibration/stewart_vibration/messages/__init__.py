"""ROS 2 messages without rclpy: serialized CDR of the suite's high-rate topics (``cdr``)."""
