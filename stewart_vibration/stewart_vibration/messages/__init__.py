"""ROS 2 messages without rclpy: serialized CDR of the suite's high-rate topics (``cdr``: the wire format;
``joint_states``, ``stamped_doubles``, ``joint_trajectory``, ``diagnostic_status``: one message family each)."""
