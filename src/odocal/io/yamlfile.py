"""YAML reading that remembers the line of every key, for error messages.

Robot, parameter and track files are small mappings written by people, so the reader is strict
and bounded where PyYAML is neither:

- numbers, booleans and nulls follow the YAML 1.2 core schema, as people read them: ``+.5``,
  ``-.5``, ``.5e-3`` and ``1e-6`` are numbers (PyYAML's YAML 1.1 leaves some of them text), and
  ``012`` is twelve, not an octal ten; ``yes``/``no``/``on``/``off`` and dates stay text;
- merge keys (``<<: *base``) work; keys given in the mapping itself win over merged ones;
- a key given twice in one mapping is an error (PyYAML silently keeps the last);
- aliases are bounded: at most :data:`MAX_ALIASES` of them and :data:`MAX_NODES` values after
  expansion (a "billion laughs" file is refused before anything is expanded: the values it
  would make are counted on the parsed graph, each node once, and the error names the key whose
  value passes the bound);
- nesting deeper than :data:`MAX_DEPTH` (and a recursive alias) is an error, never a crash;
- only the core tags (str, int, float, bool, null, map, seq) are accepted;
- a number too large for a float, or a number field longer than ``MAX_FIELD_CHARS``, is an error
  naming the file, the line and the key.
"""

from __future__ import annotations

import math
import re
from typing import Any

import yaml
from yaml.composer import Composer
from yaml.constructor import SafeConstructor
from yaml.resolver import Resolver

from ..core.checks import parse_float
from ..errors import InputError
from .limits import MAX_YAML_BYTES
from .table import MAX_FIELD_CHARS
from .textfile import read_text

__all__ = ["YamlDoc", "load_yaml", "MAX_ALIASES", "MAX_DEPTH", "MAX_NODES"]

#: Most aliases (``*name``) a file may use: a robot or track file needs a few at most.
MAX_ALIASES = 1000
#: Most values (scalars, mappings, sequences) after alias expansion.
MAX_NODES = 200_000
#: Deepest nesting of mappings and sequences (a track file needs 4).
MAX_DEPTH = 32

_TAG = "tag:yaml.org,2002:"
_STR, _INT, _FLOAT, _BOOL, _NULL = (_TAG + t for t in ("str", "int", "float", "bool", "null"))
_MAP, _SEQ, _MERGE = _TAG + "map", _TAG + "seq", _TAG + "merge"

# YAML 1.2 core schema (https://yaml.org/spec/1.2.2/#1032-tag-resolution)
_INT_RE = re.compile(r"^(?:[-+]?[0-9]+|0o[0-7]+|0x[0-9a-fA-F]+)$")
_FLOAT_RE = re.compile(
    r"^(?:[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?"
    r"|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$"
)
_BOOL_RE = re.compile(r"^(?:true|True|TRUE|false|False|FALSE)$")
_NULL_RE = re.compile(r"^(?:~|null|Null|NULL|)$")


class _Bounded:
    """Bounded composition (aliases, depth) over PyYAML's composer."""

    _path: Any
    _depth: int
    _aliases: int

    def compose_node(self, parent, index):  # noqa: D102 - PyYAML's API
        event = self.peek_event()
        line = event.start_mark.line + 1 if event.start_mark else None
        if self.check_event(yaml.AliasEvent):
            self._aliases += 1
            if self._aliases > MAX_ALIASES:
                raise InputError(
                    f"more than {MAX_ALIASES} aliases (*name): not a robot, parameter or track "
                    "file",
                    self._path,
                    line,
                )
        self._depth += 1
        if self._depth > MAX_DEPTH:
            raise InputError(f"nested more than {MAX_DEPTH} levels deep", self._path, line)
        try:
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1


class _Loader(_Bounded, yaml.SafeLoader):
    """PyYAML's safe loader with YAML 1.2 core resolution and bounded composition."""

    def __init__(self, stream, path) -> None:
        super().__init__(stream)
        self._path = path
        self._depth = 0
        self._aliases = 0


# Replace YAML 1.1's implicit resolvers (bool yes/no, sexagesimal and octal numbers, dates,
# '=' values, ...) with the YAML 1.2 core schema's; keep the merge key.
_Loader.yaml_implicit_resolvers = {}
_Loader.add_implicit_resolver(_BOOL, _BOOL_RE, list("tTfF"))
_Loader.add_implicit_resolver(_INT, _INT_RE, list("-+0123456789"))
_Loader.add_implicit_resolver(_FLOAT, _FLOAT_RE, list("-+.0123456789"))
_Loader.add_implicit_resolver(_NULL, _NULL_RE, ["~", "n", "N", ""])
_Loader.add_implicit_resolver(_MERGE, re.compile(r"^<<$"), ["<"])

try:  # libyaml's scanner and parser (events), about ten times faster than PyYAML's
    from yaml._yaml import CParser
except ImportError:  # pragma: no cover - PyYAML built without libyaml
    _CLoader: type | None = None
else:

    class _CLoaderImpl(_Bounded, Composer, CParser, SafeConstructor, Resolver):
        """:class:`_Loader` over libyaml's events: the same (Python) composer, bounds and
        resolution; only the scanning and parsing are libyaml's."""

        def __init__(self, stream, path) -> None:
            CParser.__init__(self, stream)
            Composer.__init__(self)
            SafeConstructor.__init__(self)
            Resolver.__init__(self)
            self._path = path
            self._depth = 0
            self._aliases = 0

    _CLoaderImpl.yaml_implicit_resolvers = _Loader.yaml_implicit_resolvers
    _CLoader = _CLoaderImpl


class YamlDoc:
    """A parsed YAML mapping plus the line number of each key (dotted paths, e.g. 'a.b'; list
    items as 'segments[1]', 'segments[1].straight_m', 1-based)."""

    def __init__(self, data: dict, lines: dict[str, int], path):
        self.data, self.lines, self.path = data, lines, path

    def error(self, key: str, message: str) -> InputError:
        """An InputError at ``key``'s line of the file."""
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
        """InputError for the first key of ``mapping`` not in ``allowed`` (``prefix`` + key: its
        dotted path)."""
        for k in mapping:
            if k not in allowed:
                raise self.error(
                    f"{prefix}{k}", f"unknown key; expected one of: {', '.join(allowed)}"
                )

    def text(self, key: str, value) -> str:
        """``value`` (at dotted ``key``) as a short line of text (a name or a label)."""
        if isinstance(value, (dict, list)) or value is None:
            raise self.error(key, "expected a name (text)")
        text = str(value)
        if len(text) > MAX_FIELD_CHARS or "\n" in text:
            raise self.error(key, f"expected a short name on one line, got {len(text)} characters")
        return text

    def number(
        self, key: str, value, *, positive=False, nonnegative=False, at_least=None, at_most=None
    ) -> float:
        """``value`` (found at dotted ``key``) as a finite float, with the given sign and within
        the plausible range [``at_least``, ``at_most``] when given (``at_most`` alone bounds the
        magnitude)."""
        if value is None:
            raise self.error(key, "no value (expected a number)")
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            shown = repr(value) if len(repr(value)) <= 40 else repr(value)[:36] + "..."
            hint = ""
            if isinstance(value, str) and value.strip().lower().lstrip("+-") in (
                "nan",
                "inf",
                "infinity",
            ):
                hint = " (text; and a value must be finite)"
            raise self.error(key, f"expected a number, got {shown}{hint}")
        try:
            v = float(value)
        except OverflowError:  # an integer beyond the float range
            raise self.error(key, "number too large for a float") from None
        if not math.isfinite(v):
            raise self.error(key, f"must be finite, got {value!r}")
        if positive and v <= 0:
            raise self.error(key, f"must be > 0, got {value!r}")
        if nonnegative and v < 0:
            raise self.error(key, f"must be >= 0, got {value!r}")
        if at_least is None and at_most is not None and abs(v) > at_most:
            raise self.error(
                key,
                f"implausible value {value!r} (at most {at_most:g} in magnitude; check the units)",
            )
        if at_least is not None and (v < at_least or (at_most is not None and v > at_most)):
            hi = "" if at_most is None else f" .. {at_most:g}"
            raise self.error(
                key, f"implausible value {value!r} (expected {at_least:g}{hi}; check the units)"
            )
        return v


class _Converter:
    """Nodes -> Python values, with key lines, duplicate and merge handling, and a node budget."""

    def __init__(self, path) -> None:
        self.path = path
        self.lines: dict[str, int] = {}
        self.nodes = 0

    def value(self, node, prefix: str, depth: int) -> Any:
        self.nodes += 1
        line = node.start_mark.line + 1
        if self.nodes > MAX_NODES:
            raise InputError(
                f"more than {MAX_NODES} values once the aliases are expanded (an alias bomb?)",
                self.path,
                line,
            )
        if depth > MAX_DEPTH:  # also a recursive alias (&a [*a])
            raise InputError(
                f"nested more than {MAX_DEPTH} levels deep (or a recursive alias)", self.path, line
            )
        if isinstance(node, yaml.MappingNode):
            if node.tag != _MAP:
                raise self._tag(node, prefix)
            return self.mapping(node, prefix, depth)
        if isinstance(node, yaml.SequenceNode):
            if node.tag != _SEQ:
                raise self._tag(node, prefix)
            items = []
            for i, v in enumerate(node.value, 1):  # items are 'key[1]', 'key[2]', ... (1-based)
                item = f"{prefix.rstrip('.')}[{i}]"
                self.lines[item] = v.start_mark.line + 1
                items.append(self.value(v, item + ".", depth + 1))
            return items
        return self.scalar(node, prefix)

    def _tag(self, node, prefix: str) -> InputError:
        tag = node.tag.replace(_TAG, "!!")
        return InputError(
            f"unsupported tag {tag}; plain values, mappings and lists only",
            self.path,
            node.start_mark.line + 1,
            prefix.rstrip(".") or None,
        )

    def key(self, node, prefix: str) -> str:
        if not isinstance(node, yaml.ScalarNode) or node.tag not in (_STR, _INT, _FLOAT, _BOOL):
            raise InputError(
                "a key must be a plain name", self.path, node.start_mark.line + 1, prefix or None
            )
        return str(node.value)

    def mapping(self, node, prefix: str, depth: int) -> dict:
        if depth > MAX_DEPTH:  # a merge of itself (&a {<<: *a})
            raise InputError(
                f"nested more than {MAX_DEPTH} levels deep (or a recursive alias)",
                self.path,
                node.start_mark.line + 1,
            )
        out: dict[str, Any] = {}
        seen: dict[str, int] = {}
        merges: list[Any] = []
        for knode, vnode in node.value:
            line = knode.start_mark.line + 1
            if isinstance(knode, yaml.ScalarNode) and knode.tag == _MERGE:
                if merges:
                    raise InputError(
                        "merge key '<<' given twice in one mapping", self.path, line, prefix or None
                    )
                merges = vnode.value if isinstance(vnode, yaml.SequenceNode) else [vnode]
                for m in merges:
                    if not isinstance(m, yaml.MappingNode):
                        raise InputError(
                            "a merge key '<<' takes a mapping or a list of mappings",
                            self.path,
                            line,
                            prefix or None,
                        )
                continue
            key = self.key(knode, prefix)
            if key in seen:
                raise InputError(
                    f"key given twice (first on line {seen[key]})", self.path, line, prefix + key
                )
            seen[key] = line
            self.lines[prefix + key] = line
            out[key] = self.value(vnode, f"{prefix}{key}.", depth + 1)
        # merged keys: the mapping's own keys win; among merged mappings, the first wins
        for m in merges:
            own_lines, self.lines = self.lines, {}
            merged = self.mapping(m, prefix, depth + 1)
            merged_lines, self.lines = self.lines, own_lines
            for key, value in merged.items():
                if key not in out:
                    out[key] = value
                    self.lines.update(
                        (k, v)
                        for k, v in merged_lines.items()
                        if k == prefix + key or k.startswith(f"{prefix}{key}.")
                    )
        return out

    def scalar(self, node, prefix: str) -> Any:
        text, tag, line = node.value, node.tag, node.start_mark.line + 1
        field = prefix.rstrip(".") or None
        if tag == _STR:
            return text
        if tag == _NULL:
            return None
        if tag == _BOOL:
            return text.lower() == "true"
        if tag in (_INT, _FLOAT):
            if len(text) > MAX_FIELD_CHARS:
                raise InputError(
                    f"over-long number ({len(text)} characters)", self.path, line, field
                )
            try:
                if tag == _INT and _INT_RE.match(text):
                    if text.startswith(("0x", "0o")):
                        return int(text[2:], 16 if text[1] == "x" else 8)
                    return int(text, 10)
                low = text.lower()
                if low.lstrip("+-") == ".inf":
                    return -math.inf if low.startswith("-") else math.inf
                if low == ".nan":
                    return math.nan
                v = parse_float(text)
            except ValueError:
                raise InputError(f"not a number: {text!r}", self.path, line, field) from None
            if math.isinf(v):
                raise InputError(
                    f"number too large for a float: {text[:24]}", self.path, line, field
                )
            return v
        raise self._tag(node, prefix)


def _values(node, memo: dict[int, int], depth: int = 0) -> int:
    """How many values :class:`_Converter` makes of ``node`` (itself, then its items, its
    mapping's values and its merged mappings' values), counted on the graph: each node is
    visited once, however many aliases name it. Below MAX_DEPTH only (deeper nesting, and a
    recursive alias, is the converter's error)."""
    if id(node) in memo:
        return memo[id(node)]
    if depth > MAX_DEPTH:
        return 0
    count = 1
    if isinstance(node, yaml.SequenceNode):
        count += sum(_values(v, memo, depth + 1) for v in node.value)
    elif isinstance(node, yaml.MappingNode):
        for knode, vnode in node.value:
            if isinstance(knode, yaml.ScalarNode) and knode.tag == _MERGE:
                merged = vnode.value if isinstance(vnode, yaml.SequenceNode) else [vnode]
                count += sum(_values(m, memo, depth + 1) - 1 for m in merged)
            else:
                count += _values(vnode, memo, depth + 1)
    memo[id(node)] = count
    return count


def _check_expansion(node, path) -> None:
    """Refuse a document that expands to more than MAX_NODES values (an alias bomb), before
    expanding it, naming the top-level key whose value passes the bound."""
    memo: dict[int, int] = {}
    if _values(node, memo) <= MAX_NODES:
        return
    line = node.start_mark.line + 1
    if isinstance(node, yaml.MappingNode):
        count = 1
        for knode, vnode in node.value:
            count += _values(vnode, memo, 1)
            if count > MAX_NODES:
                line = knode.start_mark.line + 1
                break
    raise InputError(
        f"more than {MAX_NODES} values once the aliases are expanded (an alias bomb?)", path, line
    )


def load_yaml(path, what: str = "YAML file") -> YamlDoc:
    """Parse a YAML file whose top level must be a mapping (see the module docstring).

    Parsed with libyaml where PyYAML has it; a file it refuses (or anything else going wrong
    on that way) is judged again by PyYAML's own parser, whose verdict and messages are the
    ones kept: libyaml only speeds up the files both accept."""
    text = read_text(path, max_bytes=MAX_YAML_BYTES)
    if _CLoader is not None:
        try:
            return _load(text, path, what, _CLoader)
        except Exception:  # noqa: BLE001 - the pure-Python parser decides, as without libyaml
            pass
    return _load(text, path, what, _Loader)


def _load(text: str, path, what: str, loader_class: type) -> YamlDoc:
    """:func:`load_yaml` of ``text`` with ``loader_class``."""
    try:
        loader = loader_class(text, path)
    except yaml.reader.ReaderError as exc:  # PyYAML checks the characters before parsing
        raise InputError(
            f"invalid YAML: {exc.reason} (character #x{exc.character:04x})",
            path,
            text.count("\n", 0, exc.position) + 1,
        ) from None
    try:
        node = loader.get_single_node()
        if node is None:
            raise InputError(f"empty {what}", path)
        _check_expansion(node, path)
        conv = _Converter(path)
        data = conv.value(node, "", 0)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = mark.line + 1 if mark is not None else None
        problem = getattr(exc, "problem", None) or "invalid YAML"
        raise InputError(f"invalid YAML: {problem}", path, line) from None
    finally:
        loader.dispose()
    if not isinstance(data, dict):
        raise InputError(f"a {what} must be a mapping of keys to values", path, 1)
    return YamlDoc(data, conv.lines, path)
