"""Rigs and commissioning: rig files, calibrations, commissioning through the graph, the lab."""
