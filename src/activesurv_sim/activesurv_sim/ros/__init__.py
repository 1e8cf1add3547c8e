"""The ROS shell of the simulation's nodes: helpers a node wires (rclpy, messages)."""
