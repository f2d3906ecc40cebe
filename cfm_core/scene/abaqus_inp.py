"""Reading the mesh of an Abaqus input file (.inp): nodes, elements and element sets.

cfm reads .inp files itself rather than through meshio, whose reader refused lower-case element
types (``TYPE=c3d8r``), failed with a bare ``np.int64(1)`` on ``*NODE, INPUT=file`` and on a
``*NODE`` block continued by ``*INCLUDE``, and silently dropped every element after a ``**``
comment inside an ``*ELEMENT`` block (a specimen of 30 elements for 72, exit 0).

What is read, as Abaqus reads it:

- keywords, parameter names and values, element types and set names in any case, with blanks
  (``*Element, type=C3D8R`` as Abaqus/CAE writes it, ``*element,type = c3d8r``); a keyword line
  ending in a comma is continued on the next line; ``**`` comment lines and blank lines anywhere,
  also inside data blocks;
- ``*INCLUDE, INPUT=file`` anywhere, also inside a data block, and ``INPUT=file`` on ``*NODE``,
  ``*ELEMENT`` and ``*ELSET`` (a relative name is looked for beside the file that names it, then
  beside the main file);
- ``*NODE`` (several blocks; blank or missing coordinates are 0), ``*ELEMENT`` (several blocks,
  an element's node numbers continued on the next lines), ``*ELSET`` (numbers, GENERATE, names of
  other sets, repeated to add members; the ``ELSET`` parameter of ``*ELEMENT``);
- the Abaqus/CAE structure: ``*Part`` ... ``*End Part``, ``*Assembly`` with ``*Instance`` (its
  translation and rotation lines applied to the part's nodes) ... ``*End Instance``, nodes and
  elements of an independent instance, assembly-level sets with ``INSTANCE=``. A set of an
  instance is named ``INSTANCE.SET`` and also ``SET`` where no other set has that name.

The 8-node bricks (C3D8 and every variant: C3D8R, C3D8H, C3D8I, C3D8RH, C3D8T, ...) become
``hexahedron`` cells; other solids, surfaces and trusses become their meshio cell types, for
:func:`cfm_core.scene.mesh.read_hex_mesh` to refuse or ignore. ``*NSET`` and all other keywords
(materials, sections, steps) carry nothing cfm needs and are skipped. Keywords that make or move
nodes or elements in ways not read here (``*NGEN``, ``*NFILL``, ``*NCOPY``, ``*NMAP``, ``*ELGEN``,
``*ELCOPY``, ``*SYSTEM`` with data, ``*NODE, SYSTEM=C``), unknown element types and every
malformed line are refused with an :class:`~cfm_core.errors.InputError` naming the file, the line,
the value and what is allowed.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError

#: Solid elements C3D<n><letters>: node count n -> meshio cell type.
_SOLIDS = {4: "tetra", 5: "pyramid", 6: "wedge", 8: "hexahedron", 10: "tetra10", 15: "wedge15",
           20: "hexahedron20", 27: "hexahedron27"}
#: Surface elements (shells, rigid and surface elements, membranes, plane and axisymmetric ones):
#: node count -> meshio cell type.
_SURFACES = {3: "triangle", 4: "quad", 6: "triangle6", 8: "quad8", 9: "quad9"}

#: Keywords that generate or move nodes or elements: a mesh using them is not read here.
_NOT_READ = {
    "NGEN": "generates nodes", "NFILL": "generates nodes", "NCOPY": "copies nodes",
    "NMAP": "moves nodes", "ELGEN": "generates elements", "ELCOPY": "copies elements",
    "SYSTEM": "moves the nodes that follow into a local coordinate system",
}

_ALLOWED_TYPES = ("8-node bricks: C3D8 and its variants (C3D8R, C3D8H, C3D8I, C3D8RH, C3D8IH, C3D8T, ...); "
                  "other solids (C3D4, C3D6, C3D10, C3D20, ...), surfaces (S3, S4R, R3D4, M3D4, SFM3D4, "
                  "CPS4, ...), trusses (T3D2) and MASS elements are recognised and refused or ignored")


def element_kind(etype: str) -> tuple[str, int] | None:
    """The meshio cell type and node count of an Abaqus element type, or None when unknown.

    Parameters
    ----------
    etype : str
        The element type, any case (``C3D8R``, ``c3d8rh``, ``S4R``).

    Returns
    -------
    tuple of (str, int) or None
        (meshio cell type, nodes per element), e.g. ``("hexahedron", 8)`` for every C3D8 variant.
    """
    t = etype.strip().upper()
    m = re.fullmatch(r"C3D(4|5|6|8|10|15|20|27)[A-Z]*", t)
    if m:
        return _SOLIDS[int(m[1])], int(m[1])
    m = re.fullmatch(r"(?:S|STRI|R3D|M3D|SFM3D|CPS|CPE|CPEG|CAX|CGAX)([34689])[A-Z0-9]*", t)
    if m:
        return _SURFACES[int(m[1])], int(m[1])
    m = re.fullmatch(r"T[23]D([23])[A-Z]*", t)
    if m:
        return ("line", 2) if m[1] == "2" else ("line3", 3)
    if t in ("MASS", "ROTARYI"):
        return "vertex", 1
    return None


class _Line:
    """One non-blank, non-comment line: the file it is in, its number there (1-based), its text."""

    __slots__ = ("file", "number", "text")

    def __init__(self, file: Path, number: int, text: str):
        self.file, self.number, self.text = file, number, text

    @property
    def is_keyword(self) -> bool:
        return self.text.startswith("*")


class _Lines:
    """The lines of an .inp file with ``*INCLUDE`` expanded in place, with one line of look-ahead."""

    def __init__(self, path: Path, main: Path, named_at: _Line | None = None, keyword: str = "*INCLUDE",
                 read: list | None = None):
        self.main = main
        self.read = [] if read is None else read   # every file opened, in order (shared with the reader)
        self._stack: list[tuple[Path, object]] = []
        self._ahead: _Line | None = None
        self._open(path, named_at, keyword)

    def _open(self, path: Path, named_at: _Line | None, keyword: str) -> None:
        if any(path.resolve() == p.resolve() for p, _ in self._stack):
            raise InputError(f"{_where(self.main, named_at)}: {keyword}, INPUT={path.name} includes a file that is "
                             f"already being read ('{path}'), which would repeat for ever; include each file once.")
        self._stack.append((path, enumerate(_split_lines(_read_text(path, self.main, named_at, keyword)), 1)))
        self.read.append(path)

    def next(self) -> _Line | None:
        """The next line (None at the end), ``*INCLUDE`` lines replaced by the lines of their file."""
        if self._ahead is not None:
            line, self._ahead = self._ahead, None
            return line
        while self._stack:
            path, numbered = self._stack[-1]
            for number, raw in numbered:
                text = raw.strip()
                if not text or text.startswith("**"):
                    continue
                line = _Line(path, number, text)
                if text[0] == "*" and _keyword_name(text) == "INCLUDE":
                    params = _params(line, self.main)
                    self._open(_input_file(params, line, self.main, "*INCLUDE", required=True), line, "*INCLUDE")
                    break
                return line
            else:
                self._stack.pop()
        return None

    def peek(self) -> _Line | None:
        """The next line without taking it."""
        if self._ahead is None:
            self._ahead = self.next()
        return self._ahead


def _where(main: Path, line: _Line | None) -> str:
    """'mesh file MAIN, line N' (or 'line N of INCLUDED') for messages."""
    if line is None:
        return f"mesh file '{main}'"
    if line.file == main:
        return f"mesh file '{main}', line {line.number}"
    return f"mesh file '{main}', line {line.number} of '{line.file}'"


def _quote(line: _Line) -> str:
    text = line.text if len(line.text) <= 120 else line.text[:117] + "..."
    return f"'{text}'"


def _read_text(path: Path, main: Path, named_at: _Line | None, keyword: str) -> str:
    """The text of an .inp file (UTF-8, else Latin-1); a clear InputError for a compressed or binary file."""
    try:
        raw = path.read_bytes()
    except OSError as exc:
        what = f"the file '{path}' named by {keyword}" if named_at is not None else f"the file '{path}'"
        raise InputError(f"{_where(main, named_at)}: {what} cannot be read ({exc.strerror or exc}).") from None
    if raw[:2] == b"\x1f\x8b":
        raise InputError(f"{_where(main, named_at)}: '{path}' is gzip-compressed, not the text of an Abaqus input "
                         f"file; decompress it (gunzip) and give the .inp file.")
    if b"\x00" in raw[:65536]:
        raise InputError(f"{_where(main, named_at)}: '{path}' is a binary file, not the text of an Abaqus input file "
                         f"(*NODE and *ELEMENT keyword lines with their data lines).")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        return raw.decode("latin-1")  # non-ASCII text sits only in headings and comments


def _split_lines(text: str) -> list[str]:
    """Lines ended by LF, CRLF or CR only (str.splitlines would also split at Latin-1's NEL, 0x85)."""
    return text.replace("\r\n", "\n").replace("\r", "\n").split("\n")


def _keyword_name(text: str) -> str:
    """'*Element Output, ...' -> 'ELEMENTOUTPUT' (upper case, blanks removed, as Abaqus compares them)."""
    return re.sub(r"\s+", "", text[1:].split(",", 1)[0]).upper()


def _fields(text: str) -> list[str]:
    """Comma-separated fields, commas inside double quotes kept, each stripped."""
    if '"' not in text:
        return [item.strip() for item in text.split(",")]
    out, cur, quoted = [], [], False
    for ch in text:
        if ch == '"':
            quoted = not quoted
            cur.append(ch)
        elif ch == "," and not quoted:
            out.append("".join(cur).strip())
            cur = []
        else:
            cur.append(ch)
    out.append("".join(cur).strip())
    return out


def _params(line: _Line, main: Path) -> dict[str, str | None]:
    """The parameters of a keyword line: NAME (upper case, no blanks) -> value (quotes removed) or None."""
    params: dict[str, str | None] = {}
    for item in _fields(line.text)[1:]:
        if not item:
            continue
        name, eq, value = item.partition("=")
        key = re.sub(r"\s+", "", name).upper()
        if not key:
            raise InputError(f"{_where(main, line)} ({_quote(line)}): the parameter '{item}' has no name; a keyword "
                             f"line is *KEYWORD, NAME=value, NAME, ...")
        value = value.strip()
        if len(value) >= 2 and value[0] == value[-1] == '"':
            value = value[1:-1]
        params[key] = value if eq else None
    return params


def _input_file(params: dict, line: _Line, main: Path, keyword: str, required: bool = False) -> Path | None:
    """The file named by INPUT= on a keyword line, looked for beside the naming file, then the main file."""
    if "INPUT" not in params:
        if required:
            raise InputError(f"{_where(main, line)} ({_quote(line)}): {keyword} needs INPUT=file, the file to read.")
        return None
    value = params["INPUT"]
    if not value:
        raise InputError(f"{_where(main, line)} ({_quote(line)}): {keyword} has INPUT= without a file name; give "
                         f"INPUT=name.inp (relative to the folder of '{line.file.name}').")
    name = Path(value)
    tried = [name] if name.is_absolute() else list(dict.fromkeys([line.file.parent / name, main.parent / name]))
    for path in tried:
        if path.is_file():
            return path
    raise InputError(f"{_where(main, line)} ({_quote(line)}): the file INPUT={value} of {keyword} does not exist "
                     f"(looked for {' and '.join(repr(str(p)) for p in tried)}). A relative name is taken from the "
                     f"folder of the file that names it.")


def _int(token: str, line: _Line, main: Path, what: str) -> int:
    try:
        value = int(token)
    except ValueError:
        value = None
    if value is None or value <= 0:
        hint = " (the fields of a data line are separated by commas)" if len(token.split()) > 1 else ""
        raise InputError(f"{_where(main, line)} ({_quote(line)}): {what} '{token}' is not a whole number >= 1"
                         f"{hint}.")
    return value


def _float(token: str, line: _Line, main: Path, what: str) -> float:
    if not token:
        return 0.0  # Abaqus takes a blank numeric field as 0
    try:
        value = float(token.replace("D", "E").replace("d", "e"))
    except ValueError:
        value = None
    if value is None or not math.isfinite(value):
        raise InputError(f"{_where(main, line)} ({_quote(line)}): {what} '{token}' is not a finite number.")
    return value


def _data_fields(line: _Line) -> list[str]:
    """The fields of a data line, without the empty ones a trailing comma leaves."""
    items = _fields(line.text)
    while items and not items[-1]:
        items.pop()
    return items


@dataclass
class _Block:
    """One *ELEMENT block: its type, element numbers, node references and lines."""

    etype: str
    kind: str
    n: int
    cross: bool = False  # some node is named INSTANCE.NUMBER
    ids: list[int] = field(default_factory=list)
    nodes: list[list] = field(default_factory=list)  # per element: int (this body) or (instance key, int)
    lines: list[_Line] = field(default_factory=list)


@dataclass
class _Set:
    """An element set: its name as first written and its members, chunks of (body, element numbers, line)."""

    name: str
    chunks: list[tuple["_Body", np.ndarray, _Line]] = field(default_factory=list)


@dataclass
class _Body:
    """The nodes, elements and sets of one scope: the model (or assembly), a part, or an instance."""

    key: str  # '' for the model/assembly, the upper-case instance or part name otherwise
    name: str
    line: _Line | None = None
    node_row: dict[int, int] = field(default_factory=dict)
    coords: list[tuple[float, float, float]] = field(default_factory=list)
    blocks: list[_Block] = field(default_factory=list)
    element_at: dict[int, tuple[int, int]] = field(default_factory=dict)  # number -> (block, row)
    sets: dict[str, _Set] = field(default_factory=dict)
    transform: list[_Line] = field(default_factory=list)  # an instance's translation and rotation lines


@dataclass(frozen=True)
class Labels:
    """The file's own numbers of the points and cells of a mesh :func:`read_inp` returns, for
    messages (its attribute ``file_labels``): Abaqus node and element numbers, ``INSTANCE.NUMBER``
    for those of an instance, as Abaqus names them.

    Parameters
    ----------
    points : list of (int, str, list of int)
        Per body in the order of the points: its first point, its prefix (``""`` or
        ``"INSTANCE."``) and its node numbers by row.
    cells : list of (str, list of int)
        Per cell block: the prefix and the element numbers by row.
    """

    points: list
    cells: list

    def node(self, index: int) -> str:
        """The label of point ``index`` (0-based row of the mesh's points), e.g. ``"1001"``."""
        for first, prefix, numbers in self.points:
            if first <= index < first + len(numbers):
                return f"{prefix}{numbers[index - first]}"
        raise IndexError(f"point {index} is not among the {sum(len(b[2]) for b in self.points)} points read")

    def element(self, block: int, row: int) -> str:
        """The label of row ``row`` of cell block ``block``, e.g. ``"105"`` or ``"Part-1-1.105"``."""
        prefix, numbers = self.cells[block]
        return f"{prefix}{numbers[row]}"


def _prefix(body: "_Body", root: "_Body") -> str:
    return "" if body is root else f"{body.name}."


def _numbers_by_row(body: "_Body") -> list[int]:
    numbers = [0] * len(body.node_row)
    for number, row in body.node_row.items():
        numbers[row] = number
    return numbers


class _Reader:
    """The state of one reading: the bodies, the current one, and the main file for messages."""

    def __init__(self, main: Path):
        self.main = main
        self.root = _Body("", "model")
        self.body = self.root
        self.parts: dict[str, _Body] = {}
        self.instances: dict[str, _Body] = {}
        self.lines = _Lines(main, main)
        self.files = self.lines.read     # the files read: the main one, then those INPUT= names

    def fail(self, line: _Line | None, text: str) -> InputError:
        quoted = f" ({_quote(line)})" if line is not None else ""
        return InputError(f"{_where(self.main, line)}{quoted}: {text}")

    # ------------------------------------------------------------------ reading keyword by keyword
    def read(self) -> None:
        src = self.lines
        while (line := src.next()) is not None:
            if not line.is_keyword:
                continue  # data of a keyword that carries nothing cfm needs
            line = self._joined(line)
            name, params = _keyword_name(line.text), _params(line, self.main)
            if name == "NODE":
                self._nodes(line, params)
            elif name == "ELEMENT":
                self._elements(line, params)
            elif name == "ELSET":
                self._elset(line, params)
            elif name == "PART":
                self._part(line, params)
            elif name == "ENDPART":
                self._end("*Part", line)
            elif name == "INSTANCE":
                self._instance(line, params)
            elif name == "ENDINSTANCE":
                self._end("*Instance", line)
            elif name in ("ASSEMBLY", "ENDASSEMBLY"):
                if self.body is not self.root:
                    what = "*Assembly" if name == "ASSEMBLY" else "*End Assembly"
                    raise self.fail(line, f"{what} inside {self._scope_words()}, which is not closed; close it "
                                          f"first.")
            elif name in _NOT_READ and not (name == "SYSTEM" and self._no_data()):
                raise self.fail(line, f"*{name} {_NOT_READ[name]}, which cfm does not read. Write the mesh "
                                      f"out as plain *NODE and *ELEMENT data (in Abaqus/CAE: write the input "
                                      f"file of the meshed model), or export it as .vtu or .msh.")

    def _no_data(self) -> bool:
        nxt = self.lines.peek()
        return nxt is None or nxt.is_keyword

    def _joined(self, line: _Line) -> _Line:
        """A keyword line with its continuation lines (a keyword line ending in a comma continues)."""
        text = line.text
        while text.endswith(","):
            nxt = self.lines.peek()
            if nxt is None or nxt.is_keyword or re.match(r"[-+.\d]", nxt.text):
                break  # data follows: the comma was a trailing one
            text = text + " " + self.lines.next().text
        return line if text == line.text else _Line(line.file, line.number, text)

    def _data(self, line: _Line, params: dict, keyword: str):
        """The data lines of a keyword: those of its INPUT= file, then those that follow it."""
        path = _input_file(params, line, self.main, keyword)
        if path is not None:
            inner = _Lines(path, self.main, line, f"{keyword}", self.files)
            while (item := inner.next()) is not None:
                if item.is_keyword:
                    raise self.fail(item, f"the file INPUT={params['INPUT']} of {keyword} (line {line.number}) "
                                          f"must hold only data lines, but this is a keyword line.")
                yield item
        lines = self.lines
        while (nxt := lines.peek()) is not None and nxt.text[0] != "*":
            lines.next()
            yield nxt

    def _scope_words(self) -> str:
        b = self.body
        kind = "*Part" if b.key in self.parts and self.parts[b.key] is b else "*Instance"
        return f"{kind}, name={b.name} (line {b.line.number} of '{b.line.file.name}')"

    # ------------------------------------------------------------------ nodes and elements
    def _nodes(self, line: _Line, params: dict) -> None:
        system = (params.get("SYSTEM") or "R").upper()
        if system != "R":
            raise self.fail(line, f"*NODE, SYSTEM={params['SYSTEM']} gives cylindrical or spherical coordinates, "
                                  f"which cfm does not read; write the nodes in rectangular coordinates "
                                  f"(SYSTEM=R, the default).")
        body = self.body
        row_of, coords = body.node_row, body.coords
        for item in self._data(line, params, "*NODE"):
            parts = item.text.split(",")
            try:  # the usual line 'number, x, y, z', read at once
                nid, x, y, z = int(parts[0]), float(parts[1]), float(parts[2]), float(parts[3])
                usual = len(parts) == 4 and nid > 0 and not (x - x or y - y or z - z)  # v - v: nan for nan, inf
            except (ValueError, IndexError):
                usual = False
            if not usual:
                fields = _data_fields(item)
                if not fields:
                    continue
                nid = _int(fields[0], item, self.main, "the node number")
                values = fields[1:]
                if len(values) > 6:
                    raise self.fail(item, f"node {nid} has {len(values)} values after its number; a *NODE data "
                                          f"line is: node number, x, y, z (m) and at most 3 direction cosines.")
                x, y, z = (_float(v, item, self.main, f"coordinate {'xyz'[k]} of node {nid}")
                           for k, v in enumerate((values + ["", "", ""])[:3]))
            if nid in row_of:
                raise self.fail(item, f"node {nid} is defined a second time{self._in_body()}; number each node once.")
            row_of[nid] = len(coords)
            coords.append((x, y, z))

    def _in_body(self) -> str:
        return "" if self.body is self.root else f" in {self._scope_words()}"

    def _elements(self, line: _Line, params: dict) -> None:
        etype = params.get("TYPE")
        if not etype:
            raise self.fail(line, "*ELEMENT needs TYPE=..., the element type (C3D8R, C3D8, ...).")
        kind = element_kind(etype)
        if kind is None:
            raise self.fail(line, f"element type TYPE={etype} is not one cfm reads. The specimen must be "
                                  f"{_ALLOWED_TYPES}. Re-mesh it with C3D8 elements, or leave other "
                                  f"elements out of the file.")
        cell, n = kind
        body = self.body
        block = _Block(etype.upper(), cell, n)
        pending: list[str] = []
        first: _Line | None = None
        for item in self._data(line, params, f"*ELEMENT, TYPE={etype}"):
            if not pending:
                try:  # the usual line: the element number and its n node numbers, read at once
                    values = [int(v) for v in item.text.split(",")]
                except ValueError:
                    values = None
                if values is not None and len(values) == n + 1 and min(values) > 0:
                    self._element(block, values[0], values[1:], item)
                    continue
            fields = _data_fields(item)
            if not fields:
                continue
            first = first or item
            pending += fields
            if len(pending) < n + 1:
                continue  # the element's node numbers go on on the next line
            if len(pending) > n + 1:
                raise self._count_error(first, item, pending, etype, n)
            self._element(block, *self._element_numbers(block, pending, first), first)
            pending, first = [], None
        if pending:
            raise self._count_error(first, None, pending, etype, n)
        body.blocks.append(block)
        if params.get("ELSET"):
            self._add_to_set(params["ELSET"], body, np.array(block.ids, dtype=np.int64), line)

    def _count_error(self, first: _Line, last: _Line | None, fields: list[str], etype: str, n: int) -> InputError:
        if last is None:
            where = "the data end before the element is complete"
        elif last is first:
            where = "on this line"
        else:
            where = (f"on lines {first.number}-{last.number} (a line with fewer numbers is continued on the next "
                     f"one)")
        return self.fail(first, f"element {fields[0]} of TYPE={etype} has {len(fields) - 1} node numbers {where}, but "
                                f"a {etype} element has {n}: each element is its number, then its {n} node "
                                f"numbers. Check the TYPE= of this *ELEMENT block against its data lines.")

    def _element_numbers(self, block: _Block, fields: list[str], line: _Line) -> tuple[int, list]:
        """(element number, node references) of an element's fields; a node is NUMBER or INSTANCE.NUMBER."""
        eid = _int(fields[0], line, self.main, "the element number")
        refs: list = []
        for token in fields[1:]:
            inst, dot, number = token.rpartition(".")
            if dot and self.body is self.root and not re.fullmatch(r"[-+\d.eE]+", token):
                refs.append((inst.strip().strip('"'), _int(number, line, self.main, f"node of element {eid}")))
                block.cross = True
            else:
                refs.append(_int(token, line, self.main, f"the node number of element {eid}"))
        return eid, refs

    def _element(self, block: _Block, eid: int, refs: list, line: _Line) -> None:
        body = self.body
        if eid in body.element_at:
            raise self.fail(line, f"element {eid} is defined a second time{self._in_body()}; number each element "
                                  f"once.")
        body.element_at[eid] = (len(body.blocks), len(block.ids))
        block.ids.append(eid)
        block.nodes.append(refs)
        block.lines.append(line)

    # ------------------------------------------------------------------ element sets
    def _add_to_set(self, name: str, body: _Body, ids: np.ndarray, line: _Line) -> None:
        key = name.upper()
        target = self.body.sets.setdefault(key, _Set(name))
        target.chunks.append((body, ids, line))

    def _elset(self, line: _Line, params: dict) -> None:
        name = params.get("ELSET")
        if not name:
            raise self.fail(line, "*ELSET needs ELSET=name, the name of the set.")
        body = self.body
        if params.get("INSTANCE"):
            body = self._instance_named(params["INSTANCE"], line)
        generate = "GENERATE" in params
        for item in self._data(line, params, "*ELSET"):
            fields = _data_fields(item)
            if not fields:
                continue
            if generate:
                if not 2 <= len(fields) <= 3:
                    raise self.fail(item, f"*ELSET, GENERATE takes 'first, last, increment' on each data line, "
                                          f"not {len(fields)} values.")
                a, b = (_int(f, item, self.main, "the element number") for f in fields[:2])
                step = _int(fields[2], item, self.main, "the increment") if len(fields) == 3 else 1
                if b < a:
                    raise self.fail(item, f"*ELSET, GENERATE: the last element {b} is below the first {a}; "
                                          f"give 'first, last, increment' with last >= first.")
                self._add_to_set(name, body, np.arange(a, b + 1, step, dtype=np.int64), item)
                continue
            numbers = []
            for token in fields:
                if re.fullmatch(r"[-+]?\d+", token):
                    numbers.append(_int(token, item, self.main, "the element number"))
                else:
                    self._add_named(name, token, body, item)
            if numbers:
                self._add_to_set(name, body, np.array(numbers, dtype=np.int64), item)

    def _add_named(self, name: str, token: str, body: _Body, line: _Line) -> None:
        """Add the members of the set ``token`` (or ``INSTANCE.SET``, or ``INSTANCE.number``) to ``name``."""
        where = body
        ref = token.strip('"')
        inst, dot, rest = ref.rpartition(".")
        if dot and body is self.root and inst.upper() in self.instances:
            where, ref = self.instances[inst.upper()], rest
            if re.fullmatch(r"\d+", ref):
                self._add_to_set(name, where, np.array([int(ref)], dtype=np.int64), line)
                return
        source = where.sets.get(ref.upper())
        if source is None:
            known = ", ".join(repr(s.name) for s in where.sets.values()) or "none"
            raise self.fail(line, f"*ELSET, ELSET={name} names the set '{token}', which is not defined before it "
                                  f"(sets defined here: {known}); define a set before naming it, or give element "
                                  f"numbers.")
        self.body.sets.setdefault(name.upper(), _Set(name)).chunks.extend(source.chunks)

    # ------------------------------------------------------------------ parts and instances
    def _part(self, line: _Line, params: dict) -> None:
        if self.body is not self.root:
            raise self.fail(line, f"*Part inside {self._scope_words()}, which is not closed; end it first "
                                  f"(*End Part or *End Instance).")
        name = params.get("NAME")
        if not name:
            raise self.fail(line, "*Part needs NAME=..., the name its *Instance lines use.")
        if name.upper() in self.parts:
            raise self.fail(line, f"the part '{name}' is defined a second time; give each part its own name.")
        self.body = self.parts[name.upper()] = _Body(name.upper(), name, line)

    def _end(self, what: str, line: _Line) -> None:
        opened = self.body is not self.root and (
            (what == "*Part") == (self.body.key in self.parts and self.parts[self.body.key] is self.body))
        if not opened:
            raise self.fail(line, f"*End {what[1:]} without a matching {what} line before it.")
        self.body = self.root

    def _instance_named(self, name: str, line: _Line) -> _Body:
        body = self.instances.get(name.upper())
        if body is None:
            known = ", ".join(repr(b.name) for b in self.instances.values()) or "none"
            raise self.fail(line, f"INSTANCE={name} names no *Instance defined before this line (instances: "
                                  f"{known}).")
        return body

    def _instance(self, line: _Line, params: dict) -> None:
        if self.body is not self.root:
            raise self.fail(line, f"*Instance inside {self._scope_words()}, which is not closed; end it first.")
        name, part_name = params.get("NAME"), params.get("PART")
        if not name or not part_name:
            raise self.fail(line, "*Instance needs NAME=... and PART=... (an instance imported from a previous "
                                  "analysis, INSTANCE=..., is not read by cfm).")
        part = self.parts.get(part_name.upper())
        if part is None:
            known = ", ".join(repr(p.name) for p in self.parts.values()) or "none"
            raise self.fail(line, f"the instance '{name}' is of PART={part_name}, which is not defined before it "
                                  f"(parts: {known}).")
        if name.upper() in self.instances:
            raise self.fail(line, f"the instance '{name}' is defined a second time; give each instance its own name.")
        body = _Body(name.upper(), name, line, dict(part.node_row), list(part.coords), list(part.blocks),
                     dict(part.element_at))
        for key, s in part.sets.items():
            body.sets[key] = _Set(s.name, [(body, ids, at) for (_, ids, at) in s.chunks])
        while (nxt := self.lines.peek()) is not None and not nxt.is_keyword:
            body.transform.append(self.lines.next())
        if len(body.transform) > 2:
            raise self.fail(body.transform[2], f"*Instance, name={name} has {len(body.transform)} data lines; it "
                                               f"takes at most 2: the translation (x, y, z) and the rotation (a point "
                                               f"a, a point b on the axis, the angle in degrees).")
        self.instances[name.upper()] = self.body = body

    def _placement(self, body: _Body) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(translation, rotation matrix, rotation centre) of an instance: x' = c + R (x + t - c)."""
        t, rot, centre = np.zeros(3), np.eye(3), np.zeros(3)
        if body.transform:
            line = body.transform[0]
            values = _data_fields(line)
            if len(values) > 3:
                raise self.fail(line, f"the translation of *Instance, name={body.name} has {len(values)} values; "
                                      f"it takes 3 (x, y, z in m).")
            t = np.array([_float(v, line, self.main, "a translation") for v in (values + ["", "", ""])[:3]])
        if len(body.transform) == 2:
            line = body.transform[1]
            values = _data_fields(line)
            if len(values) != 7:
                raise self.fail(line, f"the rotation of *Instance, name={body.name} has {len(values)} values; it "
                                      f"takes 7: point a (x, y, z), point b (x, y, z) on the axis, the angle in "
                                      f"degrees.")
            v = [_float(x, line, self.main, "a rotation value") for x in values]
            a, b, angle = np.array(v[:3]), np.array(v[3:6]), math.radians(v[6])
            axis = b - a
            if not np.linalg.norm(axis) > 0:
                raise self.fail(line, f"the rotation axis of *Instance, name={body.name} has point a = point b; "
                                      f"give two different points.")
            k = axis / np.linalg.norm(axis)
            cross = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
            rot = np.eye(3) + math.sin(angle) * cross + (1 - math.cos(angle)) * (cross @ cross)
            centre = a
        return t, rot, centre

    # ------------------------------------------------------------------ the mesh
    def mesh(self):
        """The meshio.Mesh of the model: the model/assembly's nodes and elements, then each instance's."""
        import meshio

        if self.body is not self.root:
            raise self.fail(None, f"{self._scope_words()} is not closed at the end of the file; add its *End line.")
        bodies = [self.root, *self.instances.values()]
        if self.parts and not self.instances and not self.root.blocks:
            names = ", ".join(repr(p.name) for p in self.parts.values())
            raise self.fail(None, f"the file defines the part(s) {names} but no *Instance of them in an *Assembly, "
                                  f"so its model has no elements. Add *Assembly with *Instance, name=..., "
                                  f"part=... (Abaqus/CAE writes it), or write the mesh without *Part.")
        offset, points = {}, []
        start = 0
        for body in bodies:
            x = np.asarray(body.coords, dtype=np.float64).reshape(-1, 3)
            if body is not self.root:
                t, rot, centre = self._placement(body)
                x = centre + (x + t - centre) @ rot.T
            offset[id(body)] = start
            start += len(x)
            points.append(x)
        cells, first_block = [], {}
        for body in bodies:
            first_block[id(body)] = len(cells)
            for block in body.blocks:
                cells.append((block.kind, self._connectivity(body, block, offset)))
        cell_sets = self._cell_sets(bodies, first_block, len(cells))
        mesh = meshio.Mesh(np.vstack(points) if points else np.zeros((0, 3)), cells, cell_sets=cell_sets)
        mesh.file_labels = Labels(
            [(offset[id(b)], _prefix(b, self.root), _numbers_by_row(b)) for b in bodies],
            [(_prefix(b, self.root), blk.ids) for b in bodies for blk in b.blocks])
        return mesh

    def _connectivity(self, body: _Body, block: _Block, offset: dict) -> np.ndarray:
        if not block.cross:
            refs = np.array(block.nodes, dtype=np.int64).reshape(-1, block.n)
            known = np.fromiter(body.node_row.keys(), dtype=np.int64, count=len(body.node_row))
            rows = np.fromiter(body.node_row.values(), dtype=np.int64, count=len(body.node_row))
            order = np.argsort(known)
            known, rows = known[order], rows[order]
            at = np.minimum(np.searchsorted(known, refs), max(len(known) - 1, 0))
            found = known[at] == refs if len(known) else np.zeros(refs.shape, dtype=bool)
            if found.all():
                return offset[id(body)] + rows[at]
        out = np.empty((len(block.ids), block.n), dtype=np.int64)
        for e, refs in enumerate(block.nodes):
            for k, ref in enumerate(refs):
                where, nid = (body, ref) if isinstance(ref, int) else (self.instances.get(ref[0].upper()), ref[1])
                if where is None:
                    known = ", ".join(repr(b.name) for b in self.instances.values()) or "none"
                    raise self.fail(block.lines[e], f"element {block.ids[e]} uses node {ref[0]}.{nid}, but no "
                                                    f"*Instance is named '{ref[0]}' (instances: {known}).")
                row = where.node_row.get(nid)
                if row is None:
                    scope = "" if where is body else f" of instance '{ref[0]}'"
                    raise self.fail(block.lines[e], f"element {block.ids[e]} uses node {nid}{scope}, which no *NODE "
                                                    f"line defines{self._words_for(body)}.")
                out[e, k] = offset[id(where)] + row
        return out

    def _words_for(self, body: _Body) -> str:
        return "" if body is self.root else f" in *Instance/*Part '{body.name}'"

    def _cell_sets(self, bodies: list[_Body], first_block: dict, n_blocks: int) -> dict:
        """meshio cell_sets: the model's sets by name, each instance's as INSTANCE.SET and, unclaimed, SET."""
        resolved: list[tuple[str, list]] = []
        for body in bodies:
            for s in body.sets.values():
                per_block = [[] for _ in range(n_blocks)]
                for member_body, ids, line in s.chunks:
                    for eid in ids.tolist():
                        at = member_body.element_at.get(eid)
                        if at is None:
                            raise self.fail(line, f"the element set {s.name} names element {eid}, which no *ELEMENT "
                                                  f"line defines{self._words_for(member_body)}.")
                        per_block[first_block[id(member_body)] + at[0]].append(at[1])
                arrays = [np.unique(np.asarray(p, dtype=np.int64)) for p in per_block]
                qualified = s.name if body is self.root else f"{body.name}.{s.name}"
                resolved.append((qualified, arrays))
        sets: dict[str, list] = {}
        taken = {name.upper() for name, _ in resolved}
        bare_counts: dict[str, int] = {}
        for body in bodies[1:]:
            for key in body.sets:
                bare_counts[key] = bare_counts.get(key, 0) + 1
        for name, arrays in resolved:
            sets[name] = arrays
        for body in bodies[1:]:
            for key, s in body.sets.items():
                if key not in taken and bare_counts[key] == 1:
                    sets[s.name] = sets[f"{body.name}.{s.name}"]
        return sets


def read_inp(path) -> object:
    """Read the mesh of an Abaqus input file as a meshio.Mesh (points in file units, cell blocks, cell sets).

    See the module's docstring for what is read. Nodes are in the order of the file (those of the
    model or assembly, then each instance's), cell blocks in the order of the *ELEMENT lines,
    ``cell_sets`` as meshio gives them (per set, one array of row numbers per cell block).

    Parameters
    ----------
    path : str or Path
        The .inp file; files named by INPUT= are looked for beside the file naming them, then
        beside this one.

    Returns
    -------
    meshio.Mesh
        Points, cells and cell sets; its attribute ``file_labels`` (:class:`Labels`) gives the
        file's node and element numbers of each point and cell, for messages.

    Raises
    ------
    InputError
        A file that cannot be read, a malformed line, a keyword or element type not read here,
        a reference to an undefined node, element, set, part or instance: the message names the
        file, the line and the value.
    """
    reader = _Reader(Path(path))
    reader.read()
    return reader.mesh()


def input_files(path) -> list[Path]:
    """The files an .inp file reads besides itself: those named by ``*INCLUDE, INPUT=`` and by
    ``INPUT=`` on ``*NODE``, ``*ELEMENT`` and ``*ELSET``, included ones' included files too, each
    once, in the order read. Their content is part of the mesh, so a run's provenance and a
    sweep's cache key digest them along with the main file
    (:func:`cfm_core.runs.provenance.scene_paths`).

    Parameters
    ----------
    path : str or Path
        The .inp file.

    Returns
    -------
    list of Path
        Paths as the reader resolved them (beside the naming file, else beside ``path``).

    Raises
    ------
    InputError
        As :func:`read_inp`: the file or one it names cannot be read, or is malformed.
    """
    main = Path(path)
    cached = _INCLUDED.get(main.resolve())
    if cached is not None and cached[0] == _stamp([main, *cached[1]]):
        return list(cached[1])
    reader = _Reader(main)
    reader.read()
    seen, out = {main.resolve()}, []
    for f in reader.files:
        if f.resolve() not in seen:
            seen.add(f.resolve())
            out.append(f)
    _INCLUDED[main.resolve()] = (_stamp([main, *out]), out)
    return list(out)


#: :func:`input_files` of each main file read in this process, with the :func:`_stamp` of the files
#: it named: a run asks several times (provenance, the output's inputs, messages), and parsing a
#: 40 000-element mesh takes 0.25 s; a file changed since (mtime or size) is read again.
_INCLUDED: dict = {}


def _stamp(files) -> tuple:
    """(path, mtime in ns, size) of each file; None for one that cannot be stat'ed."""
    out = []
    for f in files:
        try:
            st = f.stat()
            out.append((str(f), st.st_mtime_ns, st.st_size))
        except OSError:
            out.append((str(f), None, None))
    return tuple(out)
