"""YAML reading that remembers the line of every key, for error messages."""

from __future__ import annotations

import math
import re

from ..errors import InputError
from .textfile import read_text

__all__ = ["YamlDoc", "load_yaml"]

# A number in exponent form without a dot (1e-6, 2E3), which YAML 1.1 leaves as a string.
_EXPONENT_NUMBER = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+")


class YamlDoc:
    """A parsed YAML mapping plus the line number of each key (dotted paths, e.g. 'a.b')."""

    def __init__(self, data: dict, lines: dict[str, int], path):
        self.data, self.lines, self.path = data, lines, path

    def error(self, key: str, message: str) -> InputError:
        return InputError(message, self.path, self.lines.get(key), key)

    def section(self, key: str, allowed: tuple[str, ...]) -> dict:
        """A nested mapping (empty if absent); unknown keys are an error."""
        value = self.data.get(key, {})
        if value is None:
            return {}
        if not isinstance(value, dict):
            raise self.error(key, "expected a mapping")
        self.check_keys(value, allowed, prefix=f"{key}.")
        return value

    def check_keys(self, mapping: dict, allowed: tuple[str, ...], prefix: str = "") -> None:
        for k in mapping:
            if k not in allowed:
                raise self.error(
                    f"{prefix}{k}", f"unknown key; expected one of: {', '.join(allowed)}"
                )

    def number(
        self, key: str, value, *, positive=False, nonnegative=False, at_least=None, at_most=None
    ) -> float:
        """``value`` (found at dotted ``key``) as a finite float, with the given sign and within
        the plausible range [``at_least``, ``at_most``] when given."""
        if isinstance(value, str) and _EXPONENT_NUMBER.fullmatch(value.strip()):
            # YAML 1.1 (PyYAML) reads 1e-6 (no dot) as text; YAML 1.2 and people read a number
            value = float(value)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.error(key, f"expected a number, got {value!r}")
        v = float(value)
        if not math.isfinite(v):
            raise self.error(key, f"must be finite, got {value!r}")
        if positive and v <= 0:
            raise self.error(key, f"must be > 0, got {value!r}")
        if nonnegative and v < 0:
            raise self.error(key, f"must be >= 0, got {value!r}")
        if (at_least is not None and v < at_least) or (at_most is not None and v > at_most):
            lo = "" if at_least is None else f"{at_least:g} .. "
            raise self.error(
                key, f"implausible value {value!r} (expected {lo or 'at most '}{at_most:g})"
            )
        return v


def _to_python(node, loader, prefix, lines):
    import yaml

    if isinstance(node, yaml.MappingNode):
        out = {}
        for knode, vnode in node.value:
            key = loader.construct_object(knode)
            if not isinstance(key, str):
                key = str(key)
            dotted = f"{prefix}{key}"
            lines[dotted] = knode.start_mark.line + 1
            out[key] = _to_python(vnode, loader, dotted + ".", lines)
        return out
    if isinstance(node, yaml.SequenceNode):
        return [_to_python(v, loader, prefix, lines) for v in node.value]
    return loader.construct_object(node)


def load_yaml(path, what: str = "YAML file") -> YamlDoc:
    """Parse a YAML file whose top level must be a mapping."""
    import yaml  # here, so that commands that read no YAML do not pay for it

    text = read_text(path)
    loader = yaml.SafeLoader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            raise InputError(f"empty {what}", path)
        lines: dict[str, int] = {}
        data = _to_python(node, loader, "", lines)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = mark.line + 1 if mark is not None else None
        problem = getattr(exc, "problem", None) or "invalid YAML"
        raise InputError(f"invalid YAML: {problem}", path, line) from None
    finally:
        loader.dispose()
    if not isinstance(data, dict):
        raise InputError(f"a {what} must be a mapping of keys to values", path, 1)
    return YamlDoc(data, lines, path)
