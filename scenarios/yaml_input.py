"""YAML a user gives, read within bounds: a file can neither exhaust memory nor nest without end.

PyYAML composes an alias as a second reference to the node it names, so a kilobyte of nested aliases (nine levels of
ten, a "billion laughs") loads quickly into a small graph of shared lists; but whatever walks that graph afterwards
(the schema's validation, the ``repr`` of a bad value in its error message) walks every expansion, 10⁹ items. A
document is therefore refused, before anything walks it, when its text is longer than :data:`MAX_BYTES`, when it
nests deeper than :data:`MAX_DEPTH`, when its aliases expand it beyond :data:`MAX_EXPANDED` nodes and characters,
or when an alias refers to the collection it is part of. Text that is not UTF-8 is refused too. Each refusal is one
:class:`RefusedDocument` line that names the source and what it accepts.

The bounds are counted while the document is composed (:class:`BoundedLoader`, a subclass of PyYAML's
``SafeLoader`` through its public ``compose_node``), so a bomb is refused after composing a few of its levels.
"""

from __future__ import annotations

from typing import Any

import yaml

from vehicle_model.errors import InputError

MAX_BYTES = 256 * 1024
"""Longest YAML text [bytes]: the largest catalogue scenario is a few kilobytes."""
MAX_DEPTH = 32
"""Deepest nesting of collections: a whole configuration nests five levels at most."""
MAX_EXPANDED = 1_000_000
"""Largest document with its aliases expanded, in nodes plus the characters of its scalars: above any text of
:data:`MAX_BYTES` written out, so only aliases can reach it."""


class DocumentOutOfBounds(yaml.YAMLError):
    """Raised by :class:`BoundedLoader`: the document crosses one of its bounds; the message says which."""


class RefusedDocument(InputError):
    """A YAML text refused by :func:`load_yaml` for what it is, not for its syntax: not UTF-8, too long, nested too
    deep, aliases expanding too far or recursive."""


class BoundedLoader(yaml.SafeLoader):
    """PyYAML's safe loader that counts, while it composes, the nesting depth and the size with aliases expanded.

    Raises :class:`DocumentOutOfBounds` as soon as a bound is crossed. The size of a node is 1 for a collection plus
    its items' sizes, 1 plus its length for a scalar; an alias counts the whole size of the node it names, every
    time it appears.

    Parameters
    ----------
    stream
        The YAML text.
    max_depth, max_expanded
        The bounds (default :data:`MAX_DEPTH`, :data:`MAX_EXPANDED`).
    """

    def __init__(self, stream: str, max_depth: int = MAX_DEPTH, max_expanded: int = MAX_EXPANDED) -> None:
        super().__init__(stream)
        self.max_depth = max_depth
        self.max_expanded = max_expanded
        self._depth = 0
        self._size: dict[int, int] = {}  # id(node) → size with aliases expanded (every node stays referenced)
        self._open: set[str] = set()  # anchors of the collections being composed

    def compose_node(self, parent: yaml.Node | None, index: Any) -> yaml.Node:
        """Compose the next node (PyYAML's own), counting its depth and expanded size; refuse it out of bounds."""
        event = self.peek_event()
        if isinstance(event, yaml.AliasEvent):
            if event.anchor in self._open:
                raise DocumentOutOfBounds(
                    f"has an alias *{event.anchor} inside the collection &{event.anchor} it refers to (a recursive "
                    "alias); write the values out"
                )
            return super().compose_node(parent, index)
        if self._depth >= self.max_depth:
            raise DocumentOutOfBounds(f"nests deeper than {self.max_depth} levels")
        anchor = event.anchor
        self._depth += 1
        if anchor is not None:
            self._open.add(anchor)
        try:
            node = super().compose_node(parent, index)
        finally:
            self._depth -= 1
            self._open.discard(anchor)
        if isinstance(node, yaml.ScalarNode):
            size = 1 + len(node.value)
        elif isinstance(node, yaml.MappingNode):
            size = 1 + sum(self._size.get(id(k), 1) + self._size.get(id(v), 1) for k, v in node.value)
        else:
            size = 1 + sum(self._size.get(id(item), 1) for item in node.value)
        if size > self.max_expanded:
            raise DocumentOutOfBounds(
                f"expands through its aliases to more than {self.max_expanded:,} nodes and characters; write the "
                "values out instead of nesting aliases"
            )
        self._size[id(node)] = size
        return node


def decode_utf8(data: bytes, source: str) -> str:
    """``data`` as text; :class:`RefusedDocument` naming ``source`` if it is not UTF-8."""
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise RefusedDocument(
            f"{source} is not UTF-8 text (byte 0x{data[exc.start]:02x} at offset {exc.start}); save it as UTF-8"
        ) from None


def load_yaml(text: str | bytes, source: str) -> Any:
    """Parse one YAML document within this module's bounds.

    Parameters
    ----------
    text
        The document (bytes must be UTF-8).
    source
        What it is, for the messages (``scenario file my.yaml``).

    Returns
    -------
    Any
        The document's value; None for an empty document (nothing but blanks and comments).

    Raises
    ------
    RefusedDocument
        One line naming ``source``: not UTF-8, longer than :data:`MAX_BYTES`, deeper than :data:`MAX_DEPTH`, aliases
        expanding beyond :data:`MAX_EXPANDED`, or a recursive alias.
    InputError
        One line naming ``source``: not valid YAML.
    """
    if isinstance(text, bytes):
        size = len(text)
        text = decode_utf8(text, source) if size <= MAX_BYTES else ""
    else:
        size = len(text.encode("utf-8", errors="surrogatepass"))
    if size > MAX_BYTES:
        raise RefusedDocument(f"{source} is {size:,} bytes long; a YAML file may hold at most {MAX_BYTES:,}")
    loader = BoundedLoader(text)
    try:
        return loader.get_single_data()
    except DocumentOutOfBounds as exc:
        raise RefusedDocument(f"{source} {exc}") from None
    except yaml.YAMLError as exc:
        reason = " ".join(str(exc).split())
        raise InputError(f"{source} is not valid YAML: {reason}") from None
    finally:
        loader.dispose()
