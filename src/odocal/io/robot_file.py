"""ROBOT.yaml (a robot and its errors) and PARAMS.yaml (a calibrated geometry).

ROBOT.yaml::

    wheel_diameter_m: 0.15          # nominal, both wheels (m)
    wheelbase_m: 0.385              # nominal (m)
    # optional nominal per-wheel diameters (default: wheel_diameter_m)
    wheel_diameter_right_m: 0.15
    wheel_diameter_left_m: 0.15
    systematic: {E_b: 1.028, E_d: 0.999, E_s: 1.0}      # default 1 (no error)
    nonsystematic: {k_r_m: 1.69e-6, k_l_m: 1.69e-6}     # metres; default 0
    measurement: {sigma_xy_m: 0.001, sigma_theta_deg: 0.1}   # default 0
    believed:                        # optional: parameters the robot runs with (default nominal)
      wheel_diameter_right_m: 0.15
      wheel_diameter_left_m: 0.15
      wheelbase_m: 0.385
    kinematics: skid_steer           # optional: differential (default), skid_steer (or tracked)
    # optional, instead of 'believed': the diff_drive_controller multipliers the robot runs with
    wheel_separation_multiplier: 1.875
    left_wheel_radius_multiplier: 1.0
    right_wheel_radius_multiplier: 1.0

PARAMS.yaml holds ``wheel_diameter_right_m``, ``wheel_diameter_left_m`` and ``wheelbase_m`` at the
top level (other keys, such as those ``odocal calibrate --out`` writes beside them, are kept for
the record and ignored).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

from ..core.model import (
    Kinematics,
    MeasurementNoise,
    NonSystematicError,
    Robot,
    SystematicError,
    WheelGeometry,
)
from ..core.plausibility import proportions_problem, robot_scale_problem
from ..errors import InputError, ModelError
from ..presets import DEFAULT_ROBOT, PRESETS
from .limits import (
    ERROR_FACTOR,
    K_MAX_M,
    ROBOT_LENGTH_M,
    SIGMA_THETA_MAX_DEG,
    SIGMA_XY_MAX_M,
)

if TYPE_CHECKING:
    from .yamlfile import YamlDoc

__all__ = ["load_robot", "load_params", "robot_from_doc", "params_yaml", "robot_yaml"]

#: The diff_drive_controller multipliers a robot file may state (what the controller ran with).
MULTIPLIERS = (
    "wheel_separation_multiplier",
    "left_wheel_radius_multiplier",
    "right_wheel_radius_multiplier",
)
#: How a robot file may name each kinematics.
_KINEMATICS: dict[str, Kinematics] = {
    "differential": "differential",
    "skid_steer": "skid-steer",
    "skid-steer": "skid-steer",
    "tracked": "skid-steer",
}

_TOP = (
    "name",
    "wheel_diameter_m",
    "wheelbase_m",
    "wheel_diameter_right_m",
    "wheel_diameter_left_m",
    "systematic",
    "nonsystematic",
    "measurement",
    "believed",
    "kinematics",
    *MULTIPLIERS,
)
_GEOMETRY = ("wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m")

# Plausible ranges (odocal.io.limits): beyond them a value is a typo or a unit mistake, and the
# equations overflow or become undefined.
_LENGTH = {"at_least": ROBOT_LENGTH_M[0], "at_most": ROBOT_LENGTH_M[1]}
_FACTOR = {"at_least": ERROR_FACTOR[0], "at_most": ERROR_FACTOR[1]}


def _geometry(doc: YamlDoc, mapping: dict, prefix: str) -> WheelGeometry:
    vals = {}
    for key in _GEOMETRY:
        if key not in mapping:
            raise InputError(f"missing required key '{prefix}{key}'", doc.path)
        vals[key] = doc.number(f"{prefix}{key}", mapping[key], positive=True, **_LENGTH)
    g = WheelGeometry(*(vals[k] for k in _GEOMETRY))
    _check_proportions(doc, g, prefix)
    return g


def _check_proportions(doc: YamlDoc, g: WheelGeometry, prefix: str = "") -> None:
    """Diameter against wheelbase (a unit slip in one of them cannot pass), and both against
    the size of any wheeled robot (a slip in both: a file in millimetres)."""
    problem = proportions_problem(g.diameter_right_m, g.diameter_left_m, g.wheelbase_m)
    if problem:
        raise InputError(problem, doc.path, None, f"{prefix}wheelbase_m")
    scale = robot_scale_problem(
        float(max(g.diameter_right_m, g.diameter_left_m)), float(g.wheelbase_m)
    )
    if scale:
        raise InputError(prefix + scale, doc.path)


def robot_from_doc(doc: YamlDoc) -> Robot:
    """The Robot a parsed ROBOT.yaml describes, every key checked (InputError naming the line)."""
    d = doc.data
    doc.check_keys(d, _TOP)
    if "name" in d:
        doc.text("name", d["name"])
    for key in ("wheel_diameter_m", "wheelbase_m"):
        if key not in d:
            raise InputError(f"missing required key '{key}'", doc.path)
    diameter = doc.number("wheel_diameter_m", d["wheel_diameter_m"], positive=True, **_LENGTH)
    wheelbase = doc.number("wheelbase_m", d["wheelbase_m"], positive=True, **_LENGTH)
    d_r = d_l = diameter
    if "wheel_diameter_right_m" in d:
        d_r = doc.number(
            "wheel_diameter_right_m", d["wheel_diameter_right_m"], positive=True, **_LENGTH
        )
    if "wheel_diameter_left_m" in d:
        d_l = doc.number(
            "wheel_diameter_left_m", d["wheel_diameter_left_m"], positive=True, **_LENGTH
        )
    nominal = WheelGeometry(d_r, d_l, wheelbase)
    _check_proportions(doc, nominal)

    s = doc.section("systematic", ("E_b", "E_d", "E_s"))
    systematic = SystematicError(
        **{k: doc.number(f"systematic.{k}", v, positive=True, **_FACTOR) for k, v in s.items()}
    )
    n = doc.section("nonsystematic", ("k_r_m", "k_l_m"))
    nonsys = NonSystematicError(
        **{
            k: doc.number(f"nonsystematic.{k}", v, nonnegative=True, at_most=K_MAX_M)
            for k, v in n.items()
        }
    )
    m = doc.section("measurement", ("sigma_xy_m", "sigma_theta_deg"))
    measurement = MeasurementNoise.from_degrees(
        doc.number(
            "measurement.sigma_xy_m",
            m.get("sigma_xy_m", 0.0),
            nonnegative=True,
            at_most=SIGMA_XY_MAX_M,
        ),
        doc.number(
            "measurement.sigma_theta_deg",
            m.get("sigma_theta_deg", 0.0),
            nonnegative=True,
            at_most=SIGMA_THETA_MAX_DEG,
        ),
    )
    believed = None
    if d.get("believed") is not None:
        b = doc.section("believed", _GEOMETRY)
        believed = _geometry(doc, b, "believed.")
    stated = [k for k in MULTIPLIERS if k in d]
    if stated:
        if believed is not None:
            raise InputError(
                f"give either 'believed' or the controller's multipliers ({', '.join(stated)}), "
                "not both: both say what the robot runs with",
                doc.path,
                None,
                stated[0],
            )
        m = {k: doc.number(k, d[k], positive=True, at_least=0.2, at_most=5.0) for k in stated}
        believed = WheelGeometry(
            nominal.diameter_right_m * m.get("right_wheel_radius_multiplier", 1.0),
            nominal.diameter_left_m * m.get("left_wheel_radius_multiplier", 1.0),
            nominal.wheelbase_m * m.get("wheel_separation_multiplier", 1.0),
        )
    kinematics: Kinematics = "differential"
    if "kinematics" in d:
        name = doc.text("kinematics", d["kinematics"]).strip().lower()
        if name not in _KINEMATICS:
            raise InputError(
                f"kinematics must be one of differential, skid_steer, tracked; got {name!r}",
                doc.path,
                None,
                "kinematics",
            )
        kinematics = _KINEMATICS[name]
    return Robot(
        nominal, systematic, nonsys, measurement, believed, kinematics, believed is not None
    )


def load_robot(spec) -> Robot:
    """A Robot from a ROBOT.yaml path, or a built-in preset name (see ``odocal.presets``); a
    Robot already loaded is itself (a file is read once per command: it may be a pipe)."""
    if isinstance(spec, Robot):
        return spec
    if spec is None:
        spec = DEFAULT_ROBOT
    if str(spec) in PRESETS:
        return PRESETS[str(spec)]
    from .yamlfile import load_yaml  # here: PyYAML only when a file is read

    doc = load_yaml(spec, "robot file")
    try:
        return robot_from_doc(doc)
    except ModelError as exc:
        raise InputError(str(exc), doc.path) from None


def load_params(path) -> WheelGeometry:
    """The geometry in a PARAMS.yaml (e.g. written by ``odocal calibrate --out``)."""
    from .yamlfile import load_yaml

    doc = load_yaml(path, "parameter file")
    return _geometry(doc, doc.data, "")


def untrusted_lines(doubts: Sequence[str]) -> list[str]:
    """Comment lines that say a file was written although its calibration is not to be trusted
    (``--force``), with the reasons; none without ``doubts``."""
    if not doubts:
        return []
    return ["# NOT TO BE TRUSTED: written with --force despite:"] + [
        "#   - " + " ".join(d.split()) for d in doubts
    ]


def params_yaml(geometry: WheelGeometry, doubts: Sequence[str] = (), **record) -> str:
    """PARAMS.yaml text for ``geometry``, with ``record`` (method, E_b, ...) kept beside it;
    with ``doubts`` (a calibration written with ``--force`` despite them) a header that lists
    them and ``trusted: false``."""
    lines = ["# odocal calibrated parameters (metres); read by --params and ROBOT.yaml 'believed'"]
    lines += untrusted_lines(doubts)
    if doubts:
        lines.append("trusted: false")
    for k, v in geometry.as_dict().items():
        lines.append(f"{k}: {v:.9g}")
    for k, v in record.items():
        lines.append(f"{k}: {v if isinstance(v, str) else format(v, '.9g')}")
    return "\n".join(lines) + "\n"


def robot_yaml(robot: Robot, comments: tuple[str, ...] = ()) -> str:
    """ROBOT.yaml text for ``robot`` (read back by :func:`load_robot` to the same values, to 9
    significant digits), with ``comments`` as header lines (what the numbers came from)."""
    import math

    n = robot.nominal
    lines = ["# odocal robot file (metres; k in metres, see docs/conventions.md)"]
    lines += [f"# {c}" for c in comments]
    lines += [
        f"wheel_diameter_m: {float(n.mean_diameter_m):.9g}",
        f"wheel_diameter_right_m: {float(n.diameter_right_m):.9g}",
        f"wheel_diameter_left_m: {float(n.diameter_left_m):.9g}",
        f"wheelbase_m: {float(n.wheelbase_m):.9g}",
        "systematic:",
        f"  E_b: {robot.systematic.E_b:.9g}",
        f"  E_d: {robot.systematic.E_d:.9g}",
        f"  E_s: {robot.systematic.E_s:.9g}",
        "nonsystematic:",
        f"  k_r_m: {robot.nonsystematic.k_r_m:.9g}",
        f"  k_l_m: {robot.nonsystematic.k_l_m:.9g}",
        "measurement:",
        f"  sigma_xy_m: {robot.measurement.sigma_xy_m:.9g}",
        f"  sigma_theta_deg: {math.degrees(robot.measurement.sigma_theta_rad):.9g}",
    ]
    if robot.believed is not None:
        lines.append("believed:")
        lines += [f"  {k}: {v:.9g}" for k, v in robot.believed.as_dict().items()]
    if robot.kinematics != "differential":
        lines.append("kinematics: skid_steer")
    return "\n".join(lines) + "\n"
