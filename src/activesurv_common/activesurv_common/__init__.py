"""The shared core: geometry and time series, camera and mount models, the sensor model and
information fusion (eq. 2). Pure (numpy, yaml); the ROS contract is ``activesurv_common.ros``."""
