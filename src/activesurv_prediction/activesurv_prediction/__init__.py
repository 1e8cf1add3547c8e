"""Prediction module: overhead tracking of the top marker and Kalman prediction of the
demand points on the rolling horizon."""
