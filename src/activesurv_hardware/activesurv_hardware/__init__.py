"""A real rig: the hardware file, our camera driver and the xy table path runner."""
