"""Imaging module (vision only): circular-marker detection, weighted ellipse fit, circle pose
from the ellipse, world observations, overhead fixes, OpenCV calibration, and the imager and
overhead_locator nodes."""
