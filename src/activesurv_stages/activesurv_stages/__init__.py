"""Stepper-stage kinematics, Zaber ASCII and GRBL serial bridges and their emulators."""
