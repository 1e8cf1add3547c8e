"""Imaging module: camera models, simulated cameras, circular-marker detection, weighted ellipse fit, circle pose, sensor model, imager node."""
