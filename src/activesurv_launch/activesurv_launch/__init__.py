"""Starting ROS 2 nodes: one process per node, component containers, in-process composition,
network namespaces."""
