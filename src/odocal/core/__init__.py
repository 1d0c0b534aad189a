"""The model and the math the other layers build on: wheel geometry and its errors, poses and SE(2)
transforms, tracks, the simulator, dead reckoning (and the skid-steer kinematics), covariance
propagation, measured runs, drift per distance driven, statistics and worker processes (numpy
and scipy only)."""
