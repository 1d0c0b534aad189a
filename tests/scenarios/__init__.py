"""Scenarios end to end: the technician's walkthrough, real-data goldens (OptiOdom, Husky) and
ROS bags written by the synthetic robot, through the command line."""
