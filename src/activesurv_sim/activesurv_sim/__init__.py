"""The simulated world: renderer, simulated cameras and stages, the xy table and its paths, and
the sensor-model experiment. The only package (with bringup's evaluation) that knows the truth."""
