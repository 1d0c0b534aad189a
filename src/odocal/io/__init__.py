"""Files only: the table reader, ROBOT.yaml/PARAMS.yaml, RUNS.csv and run files, OptiOdom, bags,
tuples, the ros2_control export, reports, and the output plan (outputs checked against the
inputs, written all or none)."""
