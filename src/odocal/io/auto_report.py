"""The Markdown report of ``odocal fit BAG --method auto --out DIR``: the JSON result in words
and tables (the app computes it; this module only writes it)."""

from __future__ import annotations

from typing import Any

__all__ = ["auto_report_markdown", "skid_report_markdown"]


def _num(v: Any, fmt: str = ".6g") -> str:
    return "-" if v is None else format(v, fmt)


def skid_report_markdown(d: dict[str, Any]) -> str:
    """The report of one skid-steer fit (``fit --kinematics skid-steer``, its ``as_dict()``)."""
    v = d["verdict"]
    m = d["track_multiplier"]
    lines = [
        f"# Skid-steer calibration of `{', '.join(d['recordings'])}`",
        "",
        f"**Verdict: {'trustworthy' if v['enough'] else 'NOT to be trusted'}**"
        + ("" if v["enough"] else ":"),
    ]
    lines += [f"- {r}" for r in v["reasons"]]
    lines += ["", "## diff_drive_controller", "", "| parameter | value |", "|---|---|"]
    lines += [f"| {k} | {_num(val)} |" for k, val in d["ros2"].items()]
    lines += [
        "",
        f"wheel_separation_multiplier {m['value']:.4f} +- {m['std_error']:.4f} (effective track "
        f"{d['effective_track_m']:.4f} m)",
    ]
    drift, nominal = d["drift_percent_per_10m"], d["nominal_drift_percent_per_10m"]
    if drift and nominal:
        lines += [
            "",
            "## Held-out drift",
            "",
            f"{drift['median']:.2f} % of {drift['piece_length_m']:g} m calibrated against "
            f"{nominal['median']:.2f} % nominal (median of {drift['pieces']} pieces)",
        ]
    if d["turn_rate"]:
        lines += ["", "## The multiplier against the turn rate", "",
                  "| yaw rate (rad/s) | multiplier | std. error |", "|---|---|---|"]  # fmt: skip
        lines += [f"| {r['yaw_rate_rad_s']:.3g} | {r['multiplier']:.4f} | {r['std_error']:.4f} |"
                  for r in d["turn_rate"]]  # fmt: skip
    if d["warnings"]:
        lines += ["", "## Warnings", ""] + [f"- {w}" for w in d["warnings"]]
    return "\n".join(lines) + "\n"


def auto_report_markdown(d: dict[str, Any]) -> str:
    """The report of one ``fit --method auto`` result (its ``as_dict()``; a skid-steer fit's:
    :func:`skid_report_markdown`)."""
    if d.get("method") == "skid-steer":
        return skid_report_markdown(d)
    v = d["verdict"]
    lines = [
        f"# Odometry calibration of `{d['bag']}`",
        "",
        f"**Verdict: {'trustworthy' if v['enough'] else 'NOT to be trusted'}**"
        + ("" if v["enough"] else ":"),
    ]
    lines += [f"- {r}" for r in v["reasons"]]
    lines += ["", "## Routes", "", "| route | used | why |", "|---|---|---|"]
    lines += [f"| {r['name']} | {'yes' if r['used'] else 'no'} | {r['reason']} |"
              for r in d["routes"]]  # fmt: skip
    lines += ["", f"## Parameters (route: {d['answer_route']})", ""]
    if d["parameters"]:
        nom = d["nominal"]
        lines += ["| parameter | nominal | calibrated | std. error |", "|---|---|---|---|"]
        for k, p in d["parameters"].items():
            se = "held" if p.get("status") == "held" else _num(p["std_error"], ".2e")
            lines.append(f"| {k} | {_num(nom[k])} | {_num(p['value'])} | {se} |")
        lines += [
            "",
            "Standard errors: cluster-robust over time blocks or runs (docs/uncertainty.md).",
        ]
    lines += [
        "",
        "## Clock offsets",
        "",
        "| source | offset (s) | std. error (s) | how |",
        "|---|---|---|---|",
    ]
    for o in d["time_offsets"]:
        se = _num(o["stderr_s"], ".4f")
        lines.append(f"| {o['source']} | {o['offset_s']:+.4f} | {se} | {o['how']} |")
    h = d["heldout"]
    lines += ["", "## Held-out check", ""]
    lines.append(h["verdict"] if h else "none")
    if d["cross_checks"]:
        lines += [
            "",
            "## Routes against each other",
            "",
            "| routes | quantity | z | agree |",
            "|---|---|---|---|",
        ]
        for x in d["cross_checks"]:
            agree = "yes" if x["agree"] else "NO"
            lines.append(
                f"| {' / '.join(x['routes'])} | {x['quantity']} | {x['z']:+.2f} | {agree} |"
            )
    c = d["covariance"]
    if c:
        lines += ["", "## Covariances (diff_drive_controller)", "",
                  f"- pose_covariance_diagonal: {c['pose_covariance_diagonal']}",
                  f"- twist_covariance_diagonal: {c['twist_covariance_diagonal']}",
                  f"- from k_r = k_l = {c['k_r_m']:.3g} m (the log's own residuals), speed "
                  f"{c['speed_m_s']:g} m/s"]  # fmt: skip
    if d["warnings"]:
        lines += ["", "## Warnings", ""] + [f"- {w}" for w in d["warnings"]]
    lines += ["", "Figures: time_offset.png (clock offsets), heldout.png (held-out check).", ""]
    return "\n".join(lines)
