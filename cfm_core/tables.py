"""The one numeric CSV reader of the project: deformation histories, measured curves, finished runs.

Rules (every reader of numeric tables goes through :func:`read_table`):

- encoding: UTF-8, with or without a byte-order mark (Excel's "CSV UTF-8" writes one; it is
  skipped). UTF-16/UTF-32 (Excel's "Unicode text"), gzip-compressed files and other encodings
  (Latin-1, Windows-1252) are refused with one paragraph saying how to save the file. The same
  decoding (:func:`decode`) reads the TOML scenes and the JSON files users give;
- lines: any line ending (LF, CRLF, CR); blank lines and lines starting with ``#`` are skipped;
  the first other line is the header;
- separator: a comma, spaces around values allowed; trailing empty cells beyond the header's
  columns (``t,a,,``, what a spreadsheet writes for empty columns) are dropped. A header with no
  comma but semicolons or tabs (outside quotes) sets that separator for the whole file (Excel's CSV
  in locales with decimal commas, "tab delimited text"); with semicolons or tabs a decimal comma is
  read as a decimal point (``1,5``; a cell with both a comma and a point, ``1.000,5``, is refused
  naming it);
- quoting: cells may be quoted by the rules of Python's :mod:`csv` module (RFC 4180: ``"t [s]"``,
  a quote inside a quoted cell doubled), as Excel and ``pandas.to_csv(quoting=QUOTE_ALL)`` write
  them; a quoted cell reads as the same cell unquoted. A quote left open at the end of its line
  is refused naming the line (a cell cannot span lines);
- header: column names, each optionally with a unit in brackets, ``t [s]`` or ``t (s)`` (the
  project's own sweep output style); a unit given must be the one the column is read in. A line
  of units under the header (``s,m/s^2``: no cell a number) is read as the columns' units;
- values: finite decimal numbers (``1.5``, ``-2e-3``, ``1.0E+00``); a Fortran ``D`` exponent,
  NaN, inf, or an empty cell (``0.001,`` under ``t,a``) is refused naming the line and the column;
- time: the time column must increase (strictly or not, as the caller asks), naming the line.

Errors are :class:`~cfm_core.errors.InputError` naming the file, the line and the column. This
module is part of the base layer: it imports nothing of the project but :mod:`cfm_core.errors`.
"""

from __future__ import annotations

import codecs
import csv
import math
import numbers
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from .errors import InputError

#: Unit spellings taken as equal (after removing spaces): canonical -> accepted forms.
UNIT_ALIASES = {
    "s": {"s", "sec", "second", "seconds"},
    "m/s^2": {"m/s^2", "m/s2", "m/s²", "ms^-2", "m*s^-2", "m.s^-2"},
    "-": {"-", "", "1"},
    "N": {"N", "newton"},
    "Pa": {"Pa"},
    "m": {"m"},
}
_HEADER_CELL = re.compile(r"^\s*([^\[\]()]*?)\s*(?:[\[(]\s*([^\[\]()]*?)\s*[\])])?\s*$")
_FORTRAN_D = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)[dD][+-]?\d+$")
_QUOTED = re.compile(r'"(?:[^"]|"")*"')
_SAVE_UTF8 = ("Save it as comma-separated values in UTF-8 (Excel: File > Save As > 'CSV UTF-8 (Comma "
              "delimited)'; LibreOffice: Text CSV, character set Unicode (UTF-8)).")


@dataclass(frozen=True)
class Table:
    """A numeric table read from a CSV file.

    Attributes
    ----------
    path : str
        The file.
    columns : tuple of str
        Column names without units.
    units : tuple of str
        The unit each column's header gave ("" when none).
    data : ndarray, shape (rows, columns)
        The values (float64, in the units read).
    lines : ndarray, shape (rows,)
        1-based line number of each row in the file.
    """

    path: str
    columns: tuple[str, ...]
    units: tuple[str, ...]
    data: np.ndarray
    lines: np.ndarray

    def column(self, name: str) -> np.ndarray:
        """The values of one column.

        Parameters
        ----------
        name : str
            Column name (without unit).

        Returns
        -------
        ndarray, shape (rows,)
            Its values.
        """
        return self.data[:, self.columns.index(name)]


def unit_header(column_units: dict) -> list[str]:
    """CSV column names with their units, ``name [unit]`` (the style of sweep.csv), the header
    :func:`read_table` reads back (the name, and the unit checked).

    Parameters
    ----------
    column_units : dict of str to str
        Column name -> SI unit, in column order (``"-"`` for dimensionless).

    Returns
    -------
    list of str
        E.g. ``["t [s]", "a_raw [m/s^2]"]``.
    """
    return [f"{name} [{unit}]" for name, unit in column_units.items()]


def _same_unit(given: str, expected: str) -> bool:
    g = given.replace(" ", "")
    forms = UNIT_ALIASES.get(expected, {expected})
    return g in {f.replace(" ", "") for f in forms} or g == expected.replace(" ", "")


#: How to save a file of each kind as UTF-8, ending the encoding messages of :func:`decode`.
_SAVE_AS = {
    "CSV": _SAVE_UTF8,
    "TOML": "Save it as UTF-8 in the editor (a Latin-1 editor writes bytes that are not UTF-8 for characters like "
            "the micro sign or the degree sign; Windows Notepad: Save As, Encoding UTF-8).",
    "JSON": "Save it as UTF-8 in the editor (Windows Notepad: Save As, Encoding UTF-8; Python: json.dump to a "
            "file opened with encoding='utf-8').",
}


def decode(path, raw: bytes, kind: str = "CSV", what: str = "") -> str:
    """Text of a file's bytes: the one decoding of every text file users give (CSV tables, TOML
    scenes, JSON summaries).

    Parameters
    ----------
    path : str or Path
        The file (for messages).
    raw : bytes
        Its content.
    kind : {"CSV", "TOML", "JSON"}
        The file's format, for the messages (how to save it as UTF-8).
    what : str
        What the file is, starting the messages (e.g. "scene file"); "" names the file alone.

    Returns
    -------
    str
        The text, a UTF-8 byte-order mark removed (Excel's "CSV UTF-8" and Windows Notepad write one).

    Raises
    ------
    InputError
        UTF-16 / UTF-32 (with or without BOM), gzip-compressed bytes, or bytes that are not UTF-8
        (Latin-1, Windows-1252), naming the line and how to save the file.
    """
    name = f"{what} '{path}'".strip()
    save = _SAVE_AS[kind]
    if raw.startswith(b"\x1f\x8b"):
        raise InputError(f"{name} is gzip-compressed; {kind} files are read as plain UTF-8 text. Decompress it first "
                         f"(gunzip FILE.gz).")
    if raw.startswith((codecs.BOM_UTF32_LE, codecs.BOM_UTF32_BE)):
        enc = "UTF-32"
    elif raw.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        enc = "UTF-16"
    elif b"\x00" in raw[:4096]:
        head = raw[:4096]
        zeros = max(head[0::2].count(0), head[1::2].count(0)) / max(len(head) // 2, 1)
        if zeros < 0.4:   # UTF-16/32 text has a zero in every other byte of its ASCII; binary data does not
            raise InputError(f"{name} is not a text file (it holds zero bytes, and not in the pattern of UTF-16 or "
                             f"UTF-32 text): a binary file; {kind} files are UTF-8 text. {save}")
        enc = "UTF-16 or UTF-32 (it contains zero bytes)"
    else:
        enc = None
    if enc is not None:
        source = " (Excel's 'Unicode text' writes this)" if kind == "CSV" else ""
        raise InputError(f"{name} is encoded as {enc}, which this reader does not accept{source}; {kind} files must "
                         f"be UTF-8. {save}")
    if raw.startswith(codecs.BOM_UTF8):
        raw = raw[len(codecs.BOM_UTF8):]
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise InputError(f"{name}, line {line}: byte 0x{raw[exc.start]:02x} is not UTF-8 text; the file is in another "
                         f"encoding (Latin-1 or Windows-1252?) and {kind} files must be UTF-8. {save}") from None


def as_float(value) -> float:
    """A real number of a TOML or JSON file (or the API) as a float, never an OverflowError.

    TOML and JSON integers are unbounded (``k1 = 1`` followed by 400 zeros); ``float()`` raises
    OverflowError for one beyond the float range (about 1.8e308). It reads here as the float the
    same number written ``1e400`` gives, +inf or -inf, which the value checks refuse as not finite.

    Parameters
    ----------
    value : int or float
        A real number (not a bool; the caller checks the type).

    Returns
    -------
    float
        ``float(value)``; +-inf for an integer beyond the float range.
    """
    try:
        return float(value)
    except OverflowError:
        return math.inf if value > 0 else -math.inf


def shown(value) -> str:
    """``repr(value)`` for a message, an integer of more than 20 digits shortened.

    Parameters
    ----------
    value : object
        The value given.

    Returns
    -------
    str
        E.g. ``"1.5"``, ``"'abc'"``; an integer of 401 digits as ``"1000...0 (an integer of 401 digits)"``.
    """
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) >= 10 ** 20:
        digits = str(abs(value))
        return f"{'-' if value < 0 else ''}{digits[:4]}...{digits[-1]} (an integer of {len(digits)} digits)"
    return repr(value)


def overflowed_to_inf(text: str, value) -> bool:
    """Whether ``value``, read from ``text``, is an infinity the user did not type: a finite number
    beyond the float range (``1e400``, ``1`` followed by 400 zeros) that reads as inf, as opposed to
    ``inf`` or ``-Infinity`` typed as such.

    Parameters
    ----------
    text : str
        What was typed.
    value : float
        What it was read as.

    Returns
    -------
    bool
    """
    return (isinstance(value, float) and math.isinf(value)
            and re.fullmatch(r"[+-]?inf(inity)?", str(text).strip(), re.IGNORECASE) is None)


def check_count(name: str, value, low: int, high: int, meaning: str) -> int:
    """A count the user gives (steps, starts, evaluations, workers), checked against its range.

    The one check of every count option: an unbounded integer (``--steps`` followed by 30 digits)
    gave an OverflowError traceback or asked numpy for exabytes, and a large one ran for days.

    Parameters
    ----------
    name : str
        How the user gave it, for the message (``"--steps"``).
    value : int
        The count given.
    low, high : int
        The allowed range, both ends included.
    meaning : str
        What it counts (with its unit where it has one), for the message.

    Returns
    -------
    int
        ``value``.

    Raises
    ------
    InputError
        ``value`` is not a whole number (a bool or a float is not) or lies outside [low, high]; one
        paragraph naming the option, the value (shortened by :func:`shown` when it is long) and the
        range.
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or not low <= value <= high:
        raise InputError(f"{name} {shown(value)} is not allowed: give a whole number from {low} to {high} "
                         f"({meaning}).")
    return int(value)


@dataclass(frozen=True)
class Dialect:
    """How the lines of one file split into cells.

    Attributes
    ----------
    separator : str
        ``","``, ``";"`` or a tab.
    decimal_comma : bool
        Whether a decimal comma is read as a decimal point (only where the separator is not a comma).
    """

    separator: str = ","
    decimal_comma: bool = False

    @property
    def name(self) -> str:
        """The separator in words, for messages (``"commas"``, ``"semicolons"``, ``"tabs"``)."""
        return {",": "commas", ";": "semicolons", "\t": "tabs"}[self.separator]


def sniff(header: str) -> Dialect:
    """The dialect of a file from its header line: commas, else semicolons, else tabs.

    Parameters
    ----------
    header : str
        The header line.

    Returns
    -------
    Dialect
        Commas when the header has one; else semicolons or tabs, with decimal commas read.
    """
    bare = _QUOTED.sub("", header)  # a separator inside a quoted name does not count
    if "," in bare:
        return Dialect()
    for sep in (";", "\t"):
        if sep in bare:
            return Dialect(sep, True)
    return Dialect()


def _cells(path, lineno: int, line: str, dialect: Dialect = Dialect(), columns: int = 1) -> list[str]:
    """The cells of one line, unquoted by :mod:`csv` rules and stripped; trailing empty cells are
    dropped down to ``columns`` (empty spreadsheet columns), so that an empty value of a column
    stays a cell to be named."""
    if line.count('"') % 2:
        raise InputError(f"'{path}', line {lineno}: a quote (\") is opened and not closed on this line; quote whole "
                         f"cells (\"t [s]\",\"a [m/s^2]\"), a quote inside a quoted cell doubled (\"\"); a cell "
                         f"cannot continue on the next line.")
    row = next(csv.reader([line], delimiter=dialect.separator, quotechar='"', skipinitialspace=True,
                          strict=False), [""])
    cells = [c.strip() for c in row] or [""]
    while len(cells) > max(columns, 1) and cells[-1] == "":
        cells.pop()  # trailing empty cells: empty spreadsheet columns
    return cells


def _decimal(cell: str, dialect: Dialect) -> str:
    """A cell with its decimal comma read as a point (semicolon or tab files)."""
    if dialect.decimal_comma and "," in cell and "." not in cell and cell.count(",") == 1:
        return cell.replace(",", ".")
    return cell


def parse_header(path, lineno: int, line: str, dialect: Dialect = Dialect()) -> tuple[list[str], list[str]]:
    """Column names and units of a header line: ``t [s]`` and ``t (s)`` give name t and unit s.

    Parameters
    ----------
    path : str or Path
        The file (for messages).
    lineno : int
        The header's line number (1-based).
    line : str
        The header line.
    dialect : Dialect, optional
        Its separator (default: commas).

    Returns
    -------
    names, units : list of str
        One per column ("" where no unit is given).

    Raises
    ------
    InputError
        A cell that is not a name with an optional bracketed unit, or a quote left open.
    """
    names, units = [], []
    for cell in _cells(path, lineno, line, dialect):
        m = _HEADER_CELL.match(cell)
        if m is None or not m.group(1):
            raise InputError(f"'{path}', line {lineno}: header cell {cell!r} is not a column name, optionally "
                             f"with a unit in brackets such as 't [s]'.")
        names.append(m.group(1))
        units.append(m.group(2) or "")
    return names, units


def _number(path, lineno: int, column: str, cell: str, unit: str, dialect: Dialect = Dialect()) -> float:
    text = _decimal(cell, dialect)
    try:
        x = float(text) if text and "_" not in text else math.nan
    except ValueError:
        x = None
    if x is None or not math.isfinite(x):
        hint = " It has a Fortran 'D' exponent: write it with 'E' (1.0E+00)." if _FORTRAN_D.match(cell) else ""
        if dialect.decimal_comma and "," in cell and "." in cell:
            hint = (" It has both a comma and a point: write numbers without thousands separators, with one "
                    "decimal comma or point.")
        u = f" (in {unit})" if unit not in ("", "-") else ""
        if not cell:
            raise InputError(f"'{path}', line {lineno}: the value of {column} is empty; every row needs a finite "
                             f"decimal number{u} in each column.")
        raise InputError(f"'{path}', line {lineno}: {column} = {cell!r} is not a finite decimal number{u}.{hint}")
    return x


def _units_row(path, lineno: int, line: str, dialect: Dialect, n: int) -> bool:
    """Whether a line is a row of units (``s,m/s^2``): as many cells as columns, none a number, each
    short and made of unit characters."""
    cells = _cells(path, lineno, line, dialect, n)
    if len(cells) != n:
        return False
    for cell in cells:
        try:
            float(_decimal(cell, dialect))
            return False
        except ValueError:
            pass
        if len(cell) > 12 or not re.fullmatch(r"[\[(]?[A-Za-z0-9/^*.²³ %-]*[\])]?", cell):
            return False
    return True


def read_table(path, columns: Sequence[str], units: Mapping[str, str] | None = None, *, exact: bool = False,
               time: str | None = "t", strict: bool = True, what: str = "table") -> Table:
    """Read a numeric CSV file by the rules of the module docstring.

    Parameters
    ----------
    path : str or Path
        The CSV file.
    columns : sequence of str
        Column names the file must have (without units).
    units : mapping, optional
        Unit each column is read in (SI, e.g. {"t": "s", "a": "m/s^2"}); a header unit that
        differs is refused. Columns not named here accept any unit annotation.
    exact : bool
        True: the header must be exactly ``columns`` in this order (units aside); False: it
        must contain them, other columns are read too.
    time : str or None
        Name of the time column that must increase (None: no order check).
    strict : bool
        True: the time column must strictly increase; False: it must not decrease.
    what : str
        What the file is, for messages (e.g. "history file").

    Returns
    -------
    Table
        Names, units, data (rows, columns) float64 and the line number of every row.

    Raises
    ------
    InputError
        Missing file, encoding, header, a cell that is not a finite number, a row of the wrong
        length, time not increasing, or no data rows; naming the file and line.
    """
    p = Path(path)
    units = dict(units or {})
    if not p.is_file():
        state = "it is a folder, not a file" if p.is_dir() else "it does not exist"
        raise InputError(f"{what} '{p}' cannot be read: {state} (expected a CSV file with the columns "
                         f"{','.join(columns)}).")
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise InputError(f"{what} '{p}' cannot be read: {exc.strerror or exc}.") from None
    text = decode(p, raw)
    lines = [(n, line) for n, line in enumerate(text.splitlines(), start=1)
             if line.strip() and not line.lstrip().startswith("#")]
    expected = ",".join(f"{c} [{units[c]}]" if c in units and units[c] != "-" else c for c in columns)
    if not lines:
        raise InputError(f"{what} '{p}' is empty; it needs a header line '{','.join(columns)}' and rows of numbers.")
    hline, header = lines[0]
    dialect = sniff(header)
    names, hunits = parse_header(p, hline, header, dialect)
    ok = names == list(columns) if exact else all(c in names for c in columns)
    if not ok:
        kind = "must be exactly" if exact else "must name the columns"
        raise InputError(f"'{p}', line {hline}: the header {kind} '{','.join(columns)}' (units optional, e.g. "
                         f"'{expected}'; values separated by commas, semicolons or tabs); got "
                         f"{header.strip()!r} (columns {names}, separated by {dialect.name}).")
    if len(lines) > 1 and _units_row(p, *lines[1], dialect, len(names)):
        row = [c.strip("[]() ") for c in _cells(p, *lines[1], dialect, len(names))]
        for j, unit in enumerate(row):
            if hunits[j] and unit and not _same_unit(unit, hunits[j]):
                raise InputError(f"'{p}', line {lines[1][0]}: column {names[j]} has the unit {hunits[j]!r} in the "
                                 f"header and {unit!r} in the line of units below it; give one.")
        hunits = [h or u for h, u in zip(hunits, row)]
        lines = [lines[0], *lines[2:]]
    for name, unit in zip(names, hunits):
        if unit and name in units and not _same_unit(unit, units[name]):
            hint = " (milliseconds: divide the times by 1000)" if unit.replace(" ", "") == "ms" else ""
            raise InputError(f"'{p}', line {hline}: column {name} is given in {unit!r} but is read in "
                             f"{units[name]!r}{hint}; convert the column to {units[name]!r} (SI) or write its "
                             f"header as '{name} [{units[name]}]'.")
    data = np.empty((len(lines) - 1, len(names)))
    for k, (n, line) in enumerate(lines[1:]):
        cells = _cells(p, n, line, dialect, len(names))
        if len(cells) != len(names):
            raise InputError(f"'{p}', line {n}: {len(cells)} values separated by {dialect.name} for the {len(names)} "
                             f"columns {','.join(names)} (the header's separator, {dialect.name}, applies to every "
                             f"line).")
        for j, cell in enumerate(cells):
            data[k, j] = _number(p, n, names[j], cell, units.get(names[j], hunits[j]), dialect)
    if data.shape[0] == 0:
        raise InputError(f"{what} '{p}': no data rows after the header (line {hline}).")
    rows = np.array([n for n, _ in lines[1:]], dtype=np.int64)
    if time is not None and time in names:
        t = data[:, names.index(time)]
        d = np.diff(t)
        bad = np.flatnonzero(d <= 0.0 if strict else d < 0.0)
        if bad.size:
            k = int(bad[0]) + 1
            word = "increase" if strict else "be in time order"
            raise InputError(f"'{p}', line {rows[k]}: {time} = {float(t[k])!r} {units.get(time, 's')} does not follow the "
                             f"previous row's {float(t[k - 1])!r}; the rows must {word}.")
    return Table(str(p), tuple(names), tuple(hunits), data, rows)
