"""Prediction module: overhead tracking of the top marker and Kalman prediction of demand points."""
