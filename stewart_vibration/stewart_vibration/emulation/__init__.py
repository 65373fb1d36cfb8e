"""Hardware emulation core (no rclpy): command following, safety, MuJoCo stepping."""
