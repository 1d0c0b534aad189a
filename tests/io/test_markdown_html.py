"""The Markdown of odocal's reports as HTML (the fleet dashboard's bag pages)."""

from __future__ import annotations

from odocal.io.auto_report import auto_report_markdown
from odocal.io.markdown_html import markdown_html
from tests.support.fleet import fake_result


def test_the_subset_the_reports_use():
    md = "\n".join([
        "# Odometry calibration of `/a/b<c>.bag`", "", "**Verdict: NOT to be trusted**:",
        "- a reason with `code` and **bold**", "- another", "", "## Routes", "",
        "| route | used | why |", "|---|---|---|", "| slam | yes | map -> base_link |",
        "| scan | no | a | b \\| c |", "", "Two lines", "of one paragraph.", "", "#hashtag",
    ])  # fmt: skip
    assert markdown_html(md) == "\n".join([
        "<h1>Odometry calibration of <code>/a/b&lt;c&gt;.bag</code></h1>",
        "<p><strong>Verdict: NOT to be trusted</strong>:</p>",
        "<ul><li>a reason with <code>code</code> and <strong>bold</strong></li>"
        "<li>another</li></ul>",
        "<h2>Routes</h2>",
        "<table><thead><tr><th>route</th><th>used</th><th>why</th></tr></thead><tbody>"
        "<tr><td>slam</td><td>yes</td><td>map -&gt; base_link</td></tr>"
        "<tr><td>scan</td><td>no</td><td>a | b | c</td></tr></tbody></table>",
        "<p>Two lines\nof one paragraph.</p>",
        "<p>#hashtag</p>",
    ]) + "\n"  # fmt: skip


def test_nothing_passes_unescaped():
    out = markdown_html('<script>alert("x")</script> & `<b>` **<i>**\n\n| <a> |\n|---|\n| "q" |')
    assert "<script>" not in out and "<b>" not in out and "<i>" not in out and "<a>" not in out
    assert "&lt;script&gt;alert(&quot;x&quot;)&lt;/script&gt; &amp;" in out
    assert "<code>&lt;b&gt;</code>" in out and "<strong>&lt;i&gt;</strong>" in out


def test_a_whole_report():
    r = fake_result("/fleet/r1/bag000", (0.05, 0.05, 0.25), (5e-5, 5e-5, 2.5e-4), enough=False)
    out = markdown_html(auto_report_markdown(r))
    assert out.count("<h2>") == 4 and out.count("<table>") == 3
    assert "<strong>Verdict: NOT to be trusted</strong>:" in out
    assert "<li>simulated doubt</li>" in out
    assert "**" not in out and "|" not in out and "`" not in out
