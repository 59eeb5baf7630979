"""Bounded YAML loading with YAML 1.2 numbers (``5e-5`` is a float, not a string).

PyYAML follows YAML 1.1, whose float pattern needs a dot (``5.0e-5``), so a configuration value
written ``5e-5`` (as ROS 2 parameter files and most people write it) would load as a string and
be rejected as "must be a number". :func:`safe_load` is ``yaml.safe_load`` with the YAML 1.2
core-schema float pattern added, and with limits, so that no file can exhaust memory or the
stack or hide a setting:

* at most :data:`MAX_BYTES` of text (:func:`load_file` reads no more than that);
* at most :data:`MAX_DEPTH` nested mappings and sequences;
* at most :data:`MAX_NODES` values once aliases are expanded (a "billion laughs" of nested
  aliases is refused), and no alias inside the collection it names (a recursive value);
* no key twice in one mapping (the second would silently replace the first; the keys a merge
  ``<<: *base`` brings in may be overridden).

A violated limit raises :class:`YamlLimitError` (a ``yaml.YAMLError``); :func:`describe` gives
any ``yaml.YAMLError`` as one line.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import yaml

from tire_estimation.errors import ConfigError

#: largest YAML text loaded, bytes
MAX_BYTES = 1_000_000
#: deepest nesting of mappings and sequences
MAX_DEPTH = 50
#: most values in a document with its aliases expanded
MAX_NODES = 100_000


class YamlLimitError(yaml.YAMLError):
    """The YAML text exceeds a limit of this module (its message is one line)."""


class _Loader(yaml.SafeLoader):
    """SafeLoader with YAML 1.2 floats, bounded depth and alias expansion, unique keys."""

    def __init__(self, stream: str) -> None:
        super().__init__(stream)
        self._depth = 0
        self._expanded = 0  # values of the document so far, aliases expanded
        self._size: dict[int, int] = {}  # id(node) -> its values, aliases expanded
        self._children: dict[int, int] = {}  # id(open collection) -> its children's values
        self._keys: list[str] = []  # where the composer is: ["radius", "n_particles"]
        self.long_scalars: dict[int, str] = {}  # id(scalar node of > 1000 chars) -> its key

    def key_path(self) -> str:
        """Where the composer is, as a user writes it: ``radius.n_particles``, ``events[0]``."""
        return "".join(
            k if k.startswith("[") or not i else f".{k}" for i, k in enumerate(self._keys)
        )

    def compose_node(self, parent: yaml.Node | None, index: Any) -> yaml.Node:
        if isinstance(index, yaml.ScalarNode):  # the value of a mapping key
            self._keys.append(str(index.value))
        elif isinstance(index, int):  # an item of a sequence
            self._keys.append(f"[{index}]")
        else:
            return self._compose(parent, index)
        try:
            return self._compose(parent, index)
        finally:
            self._keys.pop()

    def _compose(self, parent: yaml.Node | None, index: Any) -> yaml.Node:
        if parent is not None:
            self._children.setdefault(id(parent), 0)
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            node = super().compose_node(parent, index)
            if id(node) in self._children:
                raise YamlLimitError(
                    f"{_where(event.start_mark)}: alias *{event.anchor} inside the value it "
                    "names (a recursive value)"
                )
            self._count(parent, self._size.get(id(node), 1), event.start_mark)
            return node
        self._depth += 1
        if self._depth > MAX_DEPTH:
            mark = self.peek_event().start_mark
            raise YamlLimitError(f"{_where(mark)}: nested too deep (more than {MAX_DEPTH} levels)")
        node = super().compose_node(parent, index)
        self._depth -= 1
        if isinstance(node, yaml.ScalarNode) and len(node.value) > 1000:
            self.long_scalars[id(node)] = self.key_path()
        size = 1 + self._children.pop(id(node), 0)
        self._size[id(node)] = size
        # the node's children are counted already; add the node itself and its size to its
        # parent's
        self._expanded += 1
        if parent is not None:
            self._children[id(parent)] += size
        if self._expanded > MAX_NODES:
            raise YamlLimitError(f"{_where(node.start_mark)}: more than {MAX_NODES} values")
        return node

    def _count(self, parent: yaml.Node | None, size: int, mark: Any) -> None:
        self._expanded += size
        if parent is not None:
            self._children[id(parent)] += size
        if self._expanded > MAX_NODES:
            raise YamlLimitError(f"{_where(mark)}: aliases expand to more than {MAX_NODES} values")

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        seen: set[Any] = set()
        for key_node, _ in node.value:
            if not isinstance(key_node, yaml.ScalarNode) or key_node.tag.endswith(":merge"):
                continue
            key = self.construct_object(key_node)
            if key in seen:
                raise YamlLimitError(f"{_where(key_node.start_mark)}: key {key!r} given twice")
            seen.add(key)
        return super().construct_mapping(node, deep=deep)


def _where(mark: Any) -> str:
    return f"line {mark.line + 1}, column {mark.column + 1}" if mark is not None else "?"


# YAML 1.2 core schema, float: [-+]? ( \. [0-9]+ | [0-9]+ ( \. [0-9]* )? ) ( [eE] [-+]? [0-9]+ )?
# (plus PyYAML's own 1.1 forms: underscores, .inf, .nan, sexagesimal)
_FLOAT_12 = re.compile(
    r"""^(?:[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?
    |[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+][0-9]+)?
    |\.[0-9][0-9_]*(?:[eE][-+][0-9]+)?
    |[-+]?[0-9][0-9_]*(?::[0-5]?[0-9])+\.[0-9_]*
    |[-+]?\.(?:inf|Inf|INF)
    |\.(?:nan|NaN|NAN))$""",
    re.X,
)
_Loader.yaml_implicit_resolvers = {
    key: [(tag, rx) for tag, rx in resolvers if tag != "tag:yaml.org,2002:float"]
    for key, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
_Loader.add_implicit_resolver("tag:yaml.org,2002:float", _FLOAT_12, list("-+0123456789."))


def _construct_float(loader: yaml.SafeLoader, node: yaml.ScalarNode) -> Any:
    text = str(loader.construct_scalar(node))
    if re.fullmatch(r"[-+]?[0-9]+", text):  # an integer matched by the float pattern: keep int
        return _construct_int(loader, node)
    return loader.construct_yaml_float(node)


def _construct_int(loader: _Loader, node: yaml.ScalarNode) -> Any:
    try:
        return loader.construct_yaml_int(node)
    except ValueError as exc:  # more digits than Python converts (4300)
        key = loader.long_scalars.get(id(node)) or "a value"
        raise YamlLimitError(
            f"{_where(node.start_mark)}: {key} is an integer of too many digits"
        ) from exc


_Loader.add_constructor("tag:yaml.org,2002:float", _construct_float)
_Loader.add_constructor("tag:yaml.org,2002:int", _construct_int)


def safe_load(text: str) -> Any:
    """``yaml.safe_load`` with YAML 1.2 floats (``1e-5`` -> 1e-05) and the module's limits.

    Raises:
        yaml.YAMLError: not valid YAML, or :class:`YamlLimitError` for a limit exceeded.
    """
    if len(text) > MAX_BYTES:
        raise YamlLimitError(f"longer than {MAX_BYTES / 1e6:g} MB")
    loader = _Loader(text)
    try:
        return loader.get_single_data()
    finally:
        loader.dispose()


def describe(exc: yaml.YAMLError) -> str:
    """A ``yaml.YAMLError`` as one line: ``line 2, column 7: expected ',' or ']' ...``."""
    if isinstance(exc, YamlLimitError):
        return str(exc)
    if isinstance(exc, yaml.reader.ReaderError):
        char = exc.character
        code = f"#x{char:04x}" if isinstance(char, int) else repr(char)
        return f"character {code} at position {exc.position} is not allowed in YAML"
    if isinstance(exc, yaml.MarkedYAMLError):
        mark = exc.problem_mark or exc.context_mark
        problem = exc.problem or exc.context or "not valid YAML"
        context = f" ({exc.context})" if exc.context and exc.problem else ""
        return f"{_where(mark)}: {problem}{context}"
    return " ".join(str(exc).split())


def load_file(path: str | Path, field: str, error: type[ConfigError] = ConfigError) -> Any:
    """The YAML document in file ``path`` (read as UTF-8, at most :data:`MAX_BYTES`).

    Raises:
        ConfigError: (``error``) naming ``field`` and the path with one line saying why: not
            found, a directory, unreadable, too large, not UTF-8 text, not valid YAML or over
            a limit.
    """
    path = Path(path)
    try:
        with path.open("rb") as fh:
            raw = fh.read(MAX_BYTES + 1)
    except FileNotFoundError as exc:
        raise error(field, str(path), "file not found") from exc
    except IsADirectoryError as exc:
        raise error(field, str(path), "is a directory, not a file") from exc
    except OSError as exc:
        raise error(field, str(path), f"cannot read: {exc.strerror or exc}") from exc
    if len(raw) > MAX_BYTES:
        raise error(field, str(path), f"larger than {MAX_BYTES / 1e6:g} MB")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(field, str(path), f"not UTF-8 text (byte {exc.start})") from exc
    try:
        return safe_load(text)
    except YamlLimitError as exc:
        raise error(field, str(path), describe(exc)) from exc
    except yaml.YAMLError as exc:
        raise error(field, str(path), f"not valid YAML: {describe(exc)}") from exc
