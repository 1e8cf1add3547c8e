"""Configurations, orchestration, experiments, rosbag2 recording and replay, evaluation and
reports."""
