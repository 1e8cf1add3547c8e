"""Evaluation of recorded runs, beneath the orchestrator: from a bag and its run record to
``results.json`` and the reports. Importing it loads neither rclpy nor the node graph."""
