"""rosbag2 recording: the recorder node, reading and salvaging bags, an image load generator."""
