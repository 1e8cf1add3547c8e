"""Stepper-stage kinematics, Zaber ASCII and GRBL serial bridges, protocol emulators,
simulated stages and the xy table."""
