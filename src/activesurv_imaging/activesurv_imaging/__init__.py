"""Imaging module: camera models, simulated cameras, circular-marker detection, weighted
ellipse fit, circle pose from the ellipse, sensor model, and the imager node."""
