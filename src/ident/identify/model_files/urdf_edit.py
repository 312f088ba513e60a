"""Edit the ``<inertial>`` and ``<dynamics>`` elements of a URDF in place, text span by span.

The write-back changes a few elements of the user's file and nothing else: every other byte
(comments, ``<transmission>``, ``<gazebo>``, meshes, attribute order, number formatting) stays
as it is. The file is read with the standard library's expat parser, which reports where each
element starts; only the top-level ``<robot>/<link>`` and ``<robot>/<joint>`` elements are
kinematics (as for urdfdom, which Pinocchio and MuJoCo use): a ``<joint>`` inside a
``<transmission>`` or a ``<gazebo>`` block is not a joint of the robot.

Offsets are in UTF-8 bytes of the text (what expat reports); edits are applied to those bytes.
"""

from __future__ import annotations

import re
import xml.parsers.expat
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from ident.errors import ModelError
from ident.robot.inertia import URDF_INERTIA_ENTRIES

__all__ = [
    "ElementSpan",
    "UrdfSpans",
    "apply_edits",
    "dynamics_edit",
    "dynamics_text",
    "inertial_edit",
    "inertial_text",
    "spans",
]

FloatArray = npt.NDArray[np.float64]


@dataclass
class ElementSpan:
    """Where one element is in the UTF-8 bytes of a URDF.

    Attributes
    ----------
    start, end :
        ``data[start:end]`` is the element, from ``<`` to the ``>`` of its end tag.
    start_tag_end :
        End of its start tag (one past ``>``).
    end_tag_start :
        Start of its end tag ``</...>``, or ``None`` for an empty-element tag ``<x/>``.
    indent :
        The white space before the element on its line ("" when not alone on its line).
    """

    start: int
    end: int = -1
    start_tag_end: int = -1
    end_tag_start: int | None = None
    indent: str = ""


@dataclass
class LinkSpans:
    """A top-level ``<link>`` and its ``<inertial>``."""

    span: ElementSpan
    inertial: ElementSpan | None = None


@dataclass
class JointSpans:
    """A top-level ``<joint>`` and its ``<dynamics>``."""

    span: ElementSpan
    dynamics: ElementSpan | None = None


@dataclass
class UrdfSpans:
    """The top-level links and joints of a URDF and where they are.

    Attributes
    ----------
    data :
        The URDF as UTF-8 bytes (the offsets refer to it).
    links, joints :
        ``{name: spans}`` of ``<robot>/<link>`` and ``<robot>/<joint>`` elements.
    child_indent :
        The indentation step of the file (from the first nested element), default two spaces.
    """

    data: bytes
    links: dict[str, LinkSpans] = field(default_factory=dict)
    joints: dict[str, JointSpans] = field(default_factory=dict)
    child_indent: str = "  "


def _tag_end(data: bytes, start: int) -> int:
    """One past the ``>`` closing the tag that starts at ``start`` (quotes respected)."""
    quote = 0
    for i in range(start + 1, len(data)):
        c = data[i]
        if quote:
            if c == quote:
                quote = 0
        elif c in (0x22, 0x27):  # " '
            quote = c
        elif c == 0x3E:  # >
            return i + 1
    raise ModelError("URDF: a tag is not closed.")  # expat would have refused the file


def _indent(data: bytes, start: int) -> str:
    line_start = data.rfind(b"\n", 0, start) + 1
    before = data[line_start:start]
    return before.decode("utf-8") if before.strip() == b"" else ""


def spans(text: str, source: str = "URDF") -> UrdfSpans:
    """Locate the top-level links and joints of a URDF and their inertial/dynamics elements.

    Raises
    ------
    ModelError
        If the text is not well-formed XML, or a top-level link or joint has no name or
        appears twice.
    """
    data = text.encode("utf-8")
    out = UrdfSpans(data=data)
    stack: list[tuple[str, ElementSpan]] = []
    parser = xml.parsers.expat.ParserCreate(encoding="utf-8")
    owner: list[LinkSpans | JointSpans | None] = [None]
    indents: list[str] = []

    def start(tag: str, attrs: dict[str, str]) -> None:
        at = parser.CurrentByteIndex
        span = ElementSpan(start=at, start_tag_end=_tag_end(data, at), indent=_indent(data, at))
        depth = len(stack)
        if depth == 2 and not indents and span.indent:
            indents.append(span.indent)
        if depth == 1 and tag in ("link", "joint"):
            name = attrs.get("name")
            if not name:
                raise ModelError(f"{source}: a <{tag}> has no name; name it.")
            table: dict = out.links if tag == "link" else out.joints
            if name in table:
                raise ModelError(f"{source}: two <{tag}> elements are named {name!r}; rename one.")
            table[name] = owner[0] = LinkSpans(span) if tag == "link" else JointSpans(span)
        elif depth == 2 and isinstance(owner[0], LinkSpans) and tag == "inertial":
            owner[0].inertial = span
        elif depth == 2 and isinstance(owner[0], JointSpans) and tag == "dynamics":
            owner[0].dynamics = span
        stack.append((tag, span))

    def end(tag: str) -> None:
        at = parser.CurrentByteIndex
        _, span = stack.pop()
        if data.startswith(b"</", at):
            span.end_tag_start = at
            span.end = _tag_end(data, at)
        else:  # empty-element tag: expat reports the end at the start tag
            span.end = span.start_tag_end
        if len(stack) == 1:
            owner[0] = None

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    try:
        parser.Parse(data, True)
    except xml.parsers.expat.ExpatError as e:
        raise ModelError(f"{source}: not well-formed XML ({e}).") from e
    if indents:
        top = min((s.span.indent for s in out.links.values()), default="")
        step = indents[0][len(top) :] if indents[0].startswith(top) else indents[0]
        out.child_indent = step or "  "
    return out


def _fmt(value: float) -> str:
    """Shortest text that reads back as the same float (write-back must not round)."""
    return repr(float(value) + 0.0)  # + 0.0: no "-0.0"


def inertial_text(mass: float, com: FloatArray, inertia: FloatArray, indent: str, step: str) -> str:
    """An ``<inertial>`` element (first line unindented, following lines at ``indent``).

    ``com`` [m] in the link frame, ``inertia`` about the centre of mass in the link axes
    [kg*m^2], shape (3, 3); ``rpy="0 0 0"``.
    """
    inner = indent + step
    xyz = " ".join(_fmt(c) for c in com)
    moments = " ".join(
        f'{key}="{_fmt(inertia[i, j])}"' for key, (i, j) in URDF_INERTIA_ENTRIES.items()
    )
    return (
        "<inertial>\n"
        f'{inner}<origin xyz="{xyz}" rpy="0 0 0"/>\n'
        f'{inner}<mass value="{_fmt(mass)}"/>\n'
        f"{inner}<inertia {moments}/>\n"
        f"{indent}</inertial>"
    )


def dynamics_text(damping: float, friction: float) -> str:
    """A ``<dynamics damping friction>`` element [N*m*s/rad, N*m]."""
    return f'<dynamics damping="{_fmt(damping)}" friction="{_fmt(friction)}"/>'


def _put_child(
    data: bytes, parent: ElementSpan, old: ElementSpan | None, new: str, step: str
) -> tuple[int, int, bytes]:
    """The edit that replaces ``old`` (a child of ``parent``) by ``new``, or appends it."""
    if old is not None:
        return old.start, old.end, new.encode("utf-8")
    inner = parent.indent + step
    if parent.end_tag_start is None:  # <link name="x"/>: open it
        head = data[parent.start : parent.start_tag_end - 2].rstrip() + b">"
        body = f"\n{inner}{new}\n{parent.indent}</{_tag_name(data, parent)}>"
        return parent.start, parent.end, head + body.encode("utf-8")
    at = parent.end_tag_start
    line_start = data.rfind(b"\n", 0, at) + 1
    if data[line_start:at].strip() == b"":  # end tag alone on its line: insert above it
        return line_start, line_start, f"{inner}{new}\n".encode()
    return at, at, new.encode("utf-8")


def _tag_name(data: bytes, span: ElementSpan) -> str:
    head = data[span.start + 1 : span.start_tag_end].decode("utf-8")
    return head.split()[0].rstrip("/>")


def apply_edits(data: bytes, edits: Iterable[tuple[int, int, bytes]]) -> str:
    """Apply non-overlapping ``(start, end, replacement)`` byte edits; return the text."""
    out = []
    position = 0
    for start, end, replacement in sorted(edits, key=lambda e: (e[0], e[1])):
        if start < position:
            raise ValueError("overlapping edits")
        out.append(data[position:start])
        out.append(replacement)
        position = end
    out.append(data[position:])
    return b"".join(out).decode("utf-8")


def inertial_edit(
    urdf: UrdfSpans, link: str, mass: float, com: FloatArray, inertia: FloatArray
) -> tuple[int, int, bytes]:
    """The edit that gives ``link`` this inertial (replacing or adding the element)."""
    spans_ = urdf.links[link]
    if spans_.inertial is not None:
        indent = spans_.inertial.indent
    else:
        indent = spans_.span.indent + urdf.child_indent
    text = inertial_text(mass, com, inertia, indent, urdf.child_indent)
    return _put_child(urdf.data, spans_.span, spans_.inertial, text, urdf.child_indent)


def _set_attributes(data: bytes, span: ElementSpan, values: dict[str, str]) -> bytes:
    """The start tag of ``span`` with ``values`` set (other attributes and spacing kept)."""
    tag = data[span.start : span.start_tag_end].decode("utf-8")
    for key, value in values.items():
        pattern = re.compile(rf"(\s{key}\s*=\s*)(\"[^\"]*\"|'[^']*')")
        found = pattern.search(tag)
        if found:
            tag = f'{tag[: found.start()]}{found.group(1)}"{value}"{tag[found.end() :]}'
        else:
            end = len(tag) - (2 if tag.endswith("/>") else 1)
            head = tag[:end].rstrip()
            tag = f'{head} {key}="{value}"{tag[end:]}'
    return tag.encode("utf-8")


def dynamics_edit(
    urdf: UrdfSpans, joint: str, damping: float, friction: float
) -> tuple[int, int, bytes]:
    """The edit that sets ``joint``'s ``<dynamics damping friction>``.

    An existing element keeps its other attributes (e.g. a simulator's); else one is added.
    """
    spans_ = urdf.joints[joint]
    old = spans_.dynamics
    if old is not None:
        values = {"damping": _fmt(damping), "friction": _fmt(friction)}
        return old.start, old.start_tag_end, _set_attributes(urdf.data, old, values)
    return _put_child(
        urdf.data, spans_.span, None, dynamics_text(damping, friction), urdf.child_indent
    )
