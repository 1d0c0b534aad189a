"""The plausibility limits of every input, in one place (the README's "Files" section states them).

A value outside its range is refused where it enters (one line naming the file, the line and
the field, or the flag), because beyond it a value is a typo, a unit slip or a broken file, and
the equations overflow or become undefined long before. The limits are ABSOLUTE and per format:
whether a diameter fits the wheelbase, or a run sheet the track, is a relative check made where
both are known.

Importing this module imports nothing (the command line uses it for its flags).
"""

from __future__ import annotations

# --- robots: ROBOT.yaml, PARAMS.yaml, a run's ran-with parameters, OptiOdom Di/Li, flags -------

#: Wheel diameters and wheelbases (m): 0.1 mm .. 1 km.
ROBOT_LENGTH_M = (1e-4, 1e3)
#: Systematic error factors E_b, E_d, E_s: any real robot is near 1.
ERROR_FACTOR = (0.5, 2.0)
#: Wheel noise k_r, k_l (m): at most 1 m.
K_MAX_M = 1.0
#: Instrument noise: sigma_xy (m) and sigma_theta (deg).
SIGMA_XY_MAX_M = 1e3
SIGMA_THETA_MAX_DEG = 360.0

# --- tracks: track files, square sides, flags -------------------------------------------------

#: Longest track length: a side, a straight, a radius, a travel (m), 100 km.
TRACK_LENGTH_MAX_M = 1e5
#: Shortest distance an estimate or a covariance divides by (odocal noise --track and
#: --pose-distance; m): 0.1 mm. Below it a length is a unit slip (k = inf from a 1e-320 m track).
LENGTH_MIN_M = 1e-4
#: Shortest square side given in a file (m).
SIDE_MIN_M = 1e-4
#: Largest spot turn or arc angle of one segment (deg): 100 turns.
TURN_MAX_DEG = 36_000.0

# --- motion: the speed and time window of a controller's covariances (odocal noise --ros2) ----

#: Robot speed (m/s): 1 mm/s .. 10 m/s. Faster is not a wheeled robot's speed (a value in mm/s
#: typed as m/s); slower makes the twist variances vanish and a filter's matrix singular.
SPEED_M_S = (1e-3, 10.0)
#: The time over which a controller measures its velocity (s): 1 ms .. 60 s.
TWIST_WINDOW_S = (1e-3, 60.0)


def speed_problem(speed_m_s: float) -> str | None:
    """What is wrong with a robot speed (m/s), with the likely slip; None when plausible."""
    lo, hi = SPEED_M_S
    if speed_m_s > hi:
        return (
            f"{speed_m_s:g} m/s is not a plausible robot speed (at most {hi:g} m/s); did you "
            "type mm/s?"
        )
    if not speed_m_s >= lo:
        return (
            f"{speed_m_s:g} m/s is too slow for covariances (at least {lo:g} m/s: the twist "
            "variances would vanish and a filter's matrix become singular)"
        )
    return None


def twist_window_problem(window_s: float) -> str | None:
    """What is wrong with a controller's velocity window (s); None when plausible."""
    lo, hi = TWIST_WINDOW_S
    if not lo <= window_s <= hi:
        return (
            f"{window_s:g} s is not a plausible velocity window (a controller averages its "
            f"velocity over {lo:g} to {hi:g} s; diff_drive_controller: 0.2 s)"
        )
    return None


# --- encoders ---------------------------------------------------------------------------------

#: Encoder ticks per wheel revolution (a CSV setting, --ticks-per-rev, OptiOdom ngear x encRes).
TICKS_PER_REV = (1e-3, 1e9)
#: OptiOdom gear ratio ngear (motor turns per wheel turn).
GEAR_RATIO = (1e-3, 1e6)
#: OptiOdom encoder resolution encRes (counts per motor turn).
ENCODER_COUNTS = (1.0, 1e9)
#: Counter modulus of a wrapping tick counter (generic CSV '# ticks_wrap').
TICKS_WRAP = (2.0, 2.0**64)

# --- method options ---------------------------------------------------------------------------

#: The trajectory fit's heading weight (m per rad); as calibration.trajectory.MAX_HEADING_WEIGHT_M.
HEADING_WEIGHT_MAX_M = 1e3

# --- recorded values --------------------------------------------------------------------------

#: Time stamps (s): 1e12 s is 30 000 years.
TIME_MAX_S = 1e12
#: Cumulative wheel angles (rad).
WHEEL_ANGLE_MAX_RAD = 1e9
#: Cumulative encoder counts: 2^53, where floats stop counting exactly.
TICKS_MAX = 2.0**53
#: Ticks in one sample of an OptiOdom run (increments per 50 ms cycle).
TICKS_PER_SAMPLE_MAX = 1e7
#: Largest wheel rotation between two samples (rad): 160 turns; more is a glitch or a unit slip.
WHEEL_STEP_MAX_RAD = 1e3
#: Positions of a ground truth (m): larger than the Earth (UTM coordinates, 1e7 m, pass).
POSITION_MAX_M = 1e8
#: Headings (rad): unwrapped, so many turns are possible.
HEADING_MAX_RAD = 1e6
#: Angular rates (gyro, odometry twist; rad/s) and linear speeds (odometry twist; m/s).
RATE_MAX_RAD_S = 1e4
SPEED_MAX_M_S = 1e3
#: RUNS.csv values (m, deg, radius m): 1000 km, or 2778 turns.
MEASURED_MAX = 1e6

# --- text -------------------------------------------------------------------------------------

#: Largest YAML file (bytes): robot, parameter and track files are a few hundred bytes.
MAX_YAML_BYTES = 16 * 2**20
#: Largest text table (bytes): a run CSV of a whole day at 100 Hz is about 0.7 GB.
MAX_TEXT_BYTES = 2 * 2**30
