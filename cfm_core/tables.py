"""The one numeric CSV reader of the project: deformation histories, measured curves, finished runs.

Rules (every reader of numeric tables goes through :func:`read_table`):

- encoding: UTF-8, with or without a byte-order mark (Excel's "CSV UTF-8" writes one; it is
  skipped). UTF-16/UTF-32 (Excel's "Unicode text") and other encodings (Latin-1, Windows-1252)
  are refused with one paragraph saying how to save the file;
- lines: any line ending (LF, CRLF, CR); blank lines and lines starting with ``#`` are skipped;
  the first other line is the header;
- separator: a comma, spaces around values allowed; trailing empty cells (``t,a,,``, what a
  spreadsheet writes for empty columns) are dropped. A header with no comma but semicolons or tabs
  sets that separator for the whole file (Excel's CSV in locales with decimal commas, "tab
  delimited text"); with semicolons or tabs a decimal comma is read as a decimal point (``1,5``;
  a cell with both a comma and a point, ``1.000,5``, is refused naming it);
- header: column names, each optionally with a unit in brackets, ``t [s]`` or ``t (s)`` (the
  project's own sweep output style); a unit given must be the one the column is read in. A line
  of units under the header (``s,m/s^2``: no cell a number) is read as the columns' units;
- values: finite decimal numbers (``1.5``, ``-2e-3``, ``1.0E+00``); a Fortran ``D`` exponent,
  NaN, inf, or an empty cell is refused naming the line and the column;
- time: the time column must increase (strictly or not, as the caller asks), naming the line.

Errors are :class:`~cfm_core.errors.InputError` naming the file, the line and the column. This
module is part of the base layer: it imports nothing of the project but :mod:`cfm_core.errors`.
"""

from __future__ import annotations

import codecs
import math
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


def decode(path, raw: bytes) -> str:
    """Text of a CSV file's bytes.

    Parameters
    ----------
    path : str or Path
        The file (for messages).
    raw : bytes
        Its content.

    Returns
    -------
    str
        The text, a UTF-8 byte-order mark removed.

    Raises
    ------
    InputError
        UTF-16 / UTF-32 (with or without BOM) or bytes that are not UTF-8 (Latin-1, Windows-1252),
        naming the line and how to save the file.
    """
    if raw.startswith((codecs.BOM_UTF32_LE, codecs.BOM_UTF32_BE)):
        enc = "UTF-32"
    elif raw.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        enc = "UTF-16"
    elif b"\x00" in raw[:4096]:
        enc = "UTF-16 or UTF-32 (it contains zero bytes)"
    else:
        enc = None
    if enc is not None:
        raise InputError(f"'{path}' is encoded as {enc}, which this reader does not accept (Excel's 'Unicode "
                         f"text' writes this); CSV files must be UTF-8. {_SAVE_UTF8}")
    if raw.startswith(codecs.BOM_UTF8):
        raw = raw[len(codecs.BOM_UTF8):]
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise InputError(f"'{path}', line {line}: byte 0x{raw[exc.start]:02x} is not valid UTF-8; the file is in "
                         f"another encoding (Latin-1 or Windows-1252?). {_SAVE_UTF8}") from None


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
    if "," in header:
        return Dialect()
    for sep in (";", "\t"):
        if sep in header:
            return Dialect(sep, True)
    return Dialect()


def _cells(line: str, dialect: Dialect = Dialect()) -> list[str]:
    cells = [c.strip() for c in line.split(dialect.separator)]
    while len(cells) > 1 and cells[-1] == "":
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
        A cell that is not a name with an optional bracketed unit.
    """
    names, units = [], []
    for cell in _cells(line, dialect):
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
        shown = cell if cell else "(empty)"
        u = f" (in {unit})" if unit not in ("", "-") else ""
        raise InputError(f"'{path}', line {lineno}: {column} = {shown!r} is not a finite decimal number{u}.{hint}")
    return x


def _units_row(line: str, dialect: Dialect, n: int) -> bool:
    """Whether a line is a row of units (``s,m/s^2``): as many cells as columns, none a number, each
    short and made of unit characters."""
    cells = _cells(line, dialect)
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
    if len(lines) > 1 and _units_row(lines[1][1], dialect, len(names)):
        row = [c.strip("[]() ") for c in _cells(lines[1][1], dialect)]
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
        cells = _cells(line, dialect)
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
