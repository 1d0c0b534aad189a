"""The Markdown report of ``odocal fit BAG --method auto --out DIR``: the JSON result in words
and tables (the app computes it; this module only writes it)."""

from __future__ import annotations

from typing import Any

__all__ = ["auto_report_markdown"]


def _num(v: Any, fmt: str = ".6g") -> str:
    return "-" if v is None else format(v, fmt)


def auto_report_markdown(d: dict[str, Any]) -> str:
    """The report of one ``fit --method auto`` result (its ``as_dict()``)."""
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
            lines.append(
                f"| {k} | {_num(nom[k])} | {_num(p['value'])} | {_num(p['std_error'], '.2e')} |"
            )
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
