"""The one numeric CSV reader of the project: deformation histories, measured curves, finished runs.

Rules (every reader of numeric tables goes through :func:`read_table`):

- encoding: UTF-8, with or without a byte-order mark (Excel's "CSV UTF-8" writes one; it is
  skipped). UTF-16/UTF-32 (Excel's "Unicode text") and other encodings (Latin-1, Windows-1252)
  are refused with one paragraph saying how to save the file;
- lines: any line ending (LF, CRLF, CR); blank lines and lines starting with ``#`` are skipped;
  the first other line is the header;
- separator: a comma, spaces around values allowed; one trailing comma on every line is
  tolerated; semicolon-separated files (decimal commas) are refused with a hint;
- header: column names, each optionally with a unit in brackets, ``t [s]`` or ``t (s)`` (the
  project's own sweep output style); a unit given must be the one the column is read in;
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


def _cells(line: str) -> list[str]:
    cells = [c.strip() for c in line.split(",")]
    if len(cells) > 1 and cells[-1] == "":
        cells = cells[:-1]  # one trailing comma
    return cells


def parse_header(path, lineno: int, line: str) -> tuple[list[str], list[str]]:
    """Column names and units of a header line: ``t [s]`` and ``t (s)`` give name t and unit s.

    Parameters
    ----------
    path : str or Path
        The file (for messages).
    lineno : int
        The header's line number (1-based).
    line : str
        The header line.

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
    for cell in _cells(line):
        m = _HEADER_CELL.match(cell)
        if m is None or not m.group(1):
            raise InputError(f"'{path}', line {lineno}: header cell {cell!r} is not a column name, optionally "
                             f"with a unit in brackets such as 't [s]'.")
        names.append(m.group(1))
        units.append(m.group(2) or "")
    return names, units


def _number(path, lineno: int, column: str, cell: str, unit: str) -> float:
    try:
        x = float(cell) if cell and "_" not in cell else math.nan
    except ValueError:
        x = None
    if x is None or not math.isfinite(x):
        hint = " It has a Fortran 'D' exponent: write it with 'E' (1.0E+00)." if _FORTRAN_D.match(cell) else ""
        shown = cell if cell else "(empty)"
        u = f" (in {unit})" if unit not in ("", "-") else ""
        raise InputError(f"'{path}', line {lineno}: {column} = {shown!r} is not a finite decimal number{u}.{hint}")
    return x


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
        raise InputError(f"{what} '{p}' cannot be read: it does not exist (expected a CSV file with the columns "
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
    if ";" in header and "," not in header:
        raise InputError(f"'{p}', line {hline}: the columns are separated by semicolons (a spreadsheet with decimal "
                         f"commas wrote it); this reader needs commas between values and decimal points. "
                         f"{_SAVE_UTF8}")
    names, hunits = parse_header(p, hline, header)
    ok = names == list(columns) if exact else all(c in names for c in columns)
    if not ok:
        kind = "must be exactly" if exact else "must name the columns"
        raise InputError(f"'{p}', line {hline}: the header {kind} '{','.join(columns)}' (units optional, e.g. "
                         f"'{expected}'); got '{header.strip()}' (columns {names}).")
    for name, unit in zip(names, hunits):
        if unit and name in units and not _same_unit(unit, units[name]):
            hint = " (milliseconds: divide the times by 1000)" if unit.replace(" ", "") == "ms" else ""
            raise InputError(f"'{p}', line {hline}: column {name} is given in {unit!r} but is read in "
                             f"{units[name]!r}{hint}; convert the column to {units[name]!r} (SI) or write its "
                             f"header as '{name} [{units[name]}]'.")
    data = np.empty((len(lines) - 1, len(names)))
    for k, (n, line) in enumerate(lines[1:]):
        cells = _cells(line)
        if len(cells) != len(names):
            raise InputError(f"'{p}', line {n}: {len(cells)} comma-separated values for the {len(names)} columns "
                             f"{','.join(names)}.")
        for j, cell in enumerate(cells):
            data[k, j] = _number(p, n, names[j], cell, units.get(names[j], hunits[j]))
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
