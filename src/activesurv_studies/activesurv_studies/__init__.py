"""Offline studies that characterise the modules: the sensor model's two-factorial experiment
(paper Appendix A) and the prediction suite (path kinds against the predictors)."""
