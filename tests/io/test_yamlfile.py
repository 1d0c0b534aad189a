"""The YAML reader (io.yamlfile): libyaml's parser where PyYAML has it, with the same verdict,
values, key lines and messages as PyYAML's own parser."""

from __future__ import annotations

from pathlib import Path

import pytest

from odocal.errors import InputError
from odocal.io import yamlfile

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"

DOCUMENTS = [
    (EXAMPLES / "tetra-ds2.yaml").read_text(),
    "a: 1\nb: +.5\nc: -.5\nd: .5e-3\ne: 1e-6\nf: 012\ng: 0x1F\nh: 0o17\ni: yes\nj: ~\nk: True\n",
    "base: &b {x: 1, y: 2}\nother:\n  <<: *b\n  y: 3\nlist: [*b, *b]\n",
    "m:\n  <<: [{a: 1}, {a: 2, b: 2}]\n  c: 3\n",
    "text: |\n  two\n  lines\nfolded: >\n  one\n  line\nq: 'it''s'\nd: \"tab\\there\"\n",
    "# comment\r\nkey: value  # trailing\r\nseq:\r\n  - 1\r\n  - {a: [2, 3]}\r\n",
    "segments:\n  - straight_m: 1.0\n  - turn_deg: 90\n    radius_m: 0.5\n",
    "date: 2020-01-01\nsexagesimal: 1:30\nnan: .nan\ninf: -.inf\nempty:\n",
    "%YAML 1.1\n---\nk: v\n...\n",
    'k: \u00e9t\u00e9 \u2028 next\nu: "\\u263A"\n',
    # refused: each must give PyYAML's own message
    "a: 1\na: 2\n",
    "a: [1, 2\n",
    "a: b: c\n",
    "k: !!binary aGk=\n",
    "loop: &l [*l]\n",
    "deep: " + "[" * 40 + "1" + "]" * 40 + "\n",
    "a: 1\n---\nb: 2\n",
    "- 1\n- 2\n",
    "",
    "k: \x07\n",
    "k: v\n\tbad: 1\n",
    "k: 1e400\n",
    "k: '\ufeff'\n",
    "k: *undefined\n",
]


def _result(text: str, tmp_path: Path, loader) -> tuple:
    path = tmp_path / "f.yaml"
    path.write_text(text, encoding="utf-8")
    try:
        if loader is None:
            doc = yamlfile.load_yaml(path)
        else:
            doc = yamlfile._load(yamlfile.read_text(path), path, "YAML file", loader)
    except InputError as exc:
        return ("error", str(exc))
    except Exception as exc:  # noqa: BLE001 - PyYAML's own errors, compared as they are
        return ("raised", type(exc).__name__, str(exc))
    return ("ok", repr(doc.data), doc.lines)


@pytest.mark.skipif(yamlfile._CLoader is None, reason="PyYAML without libyaml")
@pytest.mark.parametrize("text", DOCUMENTS)
def test_libyaml_reads_as_pyyaml_does(text, tmp_path):
    pure = _result(text, tmp_path, yamlfile._Loader)
    assert _result(text, tmp_path, None) == pure
    if pure[0] == "ok":  # the libyaml way itself, not its fallback
        assert _result(text, tmp_path, yamlfile._CLoader) == pure


def test_a_character_yaml_does_not_allow_is_an_input_error(tmp_path):
    # (PyYAML's ReaderError used to escape load_yaml: a traceback instead of a message)
    path = tmp_path / "robot.yaml"
    path.write_text("wheelbase_m: 0.4\nwheel_diameter_m: \x07\n")
    with pytest.raises(InputError, match=r"robot.yaml, line 2: invalid YAML: special characters"):
        yamlfile.load_yaml(path)
