"""ROS-side tools of the hardware package (they import rclpy and messages)."""
