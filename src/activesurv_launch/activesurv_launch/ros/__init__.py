"""The ROS shell of the launcher: the container process and in-process composition (rclpy)."""
