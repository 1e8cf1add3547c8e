"""Fault-tolerant Optimal Region fusion of per-camera marker poses."""
