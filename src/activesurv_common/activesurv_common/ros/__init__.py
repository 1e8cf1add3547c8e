"""The ROS side of the shared core: topic names, QoS profiles, node entry point, diagnostics.

Everything here imports rclpy or message types; the modules one level up never do.
"""
