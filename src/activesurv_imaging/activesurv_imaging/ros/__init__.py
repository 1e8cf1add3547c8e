"""ROS-side helpers of the imaging package (they import rclpy and messages)."""
