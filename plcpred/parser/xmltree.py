"""The positioned XML reader of the PLCopen and TwinCAT front ends: an element tree whose
elements and text know their line and column (so that errors in ST embedded in XML point
at the file), bounded in depth and size, with no entity expansion (expat's defaults)."""
from __future__ import annotations

from xml.parsers import expat

from .errors import ProgramError
from .files import decode

MAX_XML_DEPTH = 500  # a PLCopen file nests about 12 deep; FBD/LD layouts a few more
# elements read at most: a large CODESYS export with LD/FBD layouts holds a few hundred
# thousand; 12 MB of empty elements (3 million) would take 1 GB
MAX_XML_ELEMENTS = 1_500_000
_NONE = ()      # the children and text of an element that has none (shared, never changed)
_NO_ATTRS: dict = {}   # likewise its attributes (read, never written)


class XmlElement:
    __slots__ = ("tag", "attrib", "children", "text_parts", "line", "col", "text_line",
                 "text_col")

    def __init__(self, tag, attrib, line, col):
        self.tag = tag
        self.attrib = attrib
        # made on first use: most elements of a layout have neither
        self.children: list[XmlElement] | tuple = _NONE
        self.text_parts: list[str] | tuple = _NONE
        self.line, self.col = line, col
        self.text_line = self.text_col = None

    def find(self, tag):
        return next((c for c in self.children if c.tag == tag), None)

    def findall(self, tag):
        return [c for c in self.children if c.tag == tag]

    def iter(self, tag=None):
        """This element and its descendants in document order (iteratively: nesting in
        a file is unbounded)."""
        stack = [self]
        while stack:
            el = stack.pop()
            if tag is None or el.tag == tag:
                yield el
            stack.extend(reversed(el.children))

    def all_text(self) -> tuple[str, int, int]:
        """Text of this element and its descendants, with where it starts."""
        parts, start = [], None
        for el in self.iter():
            if el.text_parts:
                parts.append("".join(el.text_parts))
                if start is None:
                    start = (el.text_line, el.text_col)
        line, col = start or (self.line, self.col)
        return "".join(parts), line, col


def parse_xml(text: str, filename: str, root: str = "project",
               what: str = "a PLCopen XML file") -> XmlElement:
    """The element tree of ``text``: a str is already decoded (its XML declaration's
    encoding is not applied again), bytes are decoded as a file is (:func:`.files.decode`:
    byte order mark, declaration)."""
    if isinstance(text, (bytes, bytearray)):
        text = decode(bytes(text), filename)
    # the encoding given here overrides the document's: the declaration (ISO-8859-1,
    # UTF-16) says what the file's bytes were, not what the str's UTF-8 encoding is
    parser = expat.ParserCreate("UTF-8")
    root_holder: list[XmlElement] = []
    stack: list[XmlElement] = []

    def local(name):
        return name.rsplit(":", 1)[-1]

    count = [0]

    def start(name, attrs):
        count[0] += 1
        if count[0] > MAX_XML_ELEMENTS:
            raise ProgramError(f"more than {MAX_XML_ELEMENTS:,} XML elements, more than "
                               "plcpred reads in one file", filename,
                               parser.CurrentLineNumber, parser.CurrentColumnNumber + 1)
        if len(stack) >= MAX_XML_DEPTH:
            raise ProgramError(f"XML elements nested more than {MAX_XML_DEPTH} deep",
                               filename, parser.CurrentLineNumber,
                               parser.CurrentColumnNumber + 1)
        el = XmlElement(local(name), {local(k): v for k, v in attrs.items()} if attrs else _NO_ATTRS,
                 parser.CurrentLineNumber, parser.CurrentColumnNumber + 1)
        if stack:
            parent = stack[-1]
            if parent.children is _NONE:
                parent.children = []
            parent.children.append(el)
        else:
            root_holder.append(el)
        stack.append(el)

    def end(name):
        stack.pop()

    def chars(data):
        el = stack[-1]
        if el.text_line is None and data.strip():
            # expat reports the position where this run of characters begins
            lead = len(data) - len(data.lstrip())
            head = data[:lead]
            line = parser.CurrentLineNumber + head.count("\n")
            col = (lead - head.rfind("\n")) if "\n" in head else parser.CurrentColumnNumber + 1 + lead
            el.text_line, el.text_col = line, col
            el.text_parts = [data[lead:]]
            return
        if el.text_line is not None or data.strip():
            if el.text_parts is _NONE:
                el.text_parts = []
            el.text_parts.append(data)

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = chars
    parser.buffer_text = False  # with buffering, positions are those of the run's end
    try:
        parser.Parse(text.encode("utf-8", "surrogatepass"), True)
    except expat.ExpatError as e:
        raise ProgramError(f"not well-formed XML: {expat.ErrorString(e.code)}", filename,
                           e.lineno, e.offset + 1) from None
    if not root_holder or root_holder[0].tag != root:
        raise ProgramError(f"not {what} (the root element must be <{root}>)",
                           filename, 1, 1)
    return root_holder[0]
