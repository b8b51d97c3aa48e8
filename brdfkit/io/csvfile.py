"""Numeric CSV files with a header: the reading and the row refusals that sample sets
(:mod:`brdfkit.io.samples`) and measurement directions (:mod:`brdfkit.io.directions`) share.

A file is one header line naming its columns, then one row of numbers per line (the
rules are in ``docs/formats.md``, "Sample CSV"). What the columns mean, and which
values a row may hold, is the caller's: this module only finds the header among the
column sets the caller accepts, parses the numbers and says which line is wrong.
"""

from __future__ import annotations

import dataclasses
import os
import re

import numpy as np

from brdfkit.atomic import check_input_file
from brdfkit.errors import FormatError

__all__ = ["CsvTable", "read_csv_table", "read_text_bytes", "decode_text"]

# Line breaks as editors count them (str.splitlines also splits on form feeds and
# Unicode separators, which would shift the line numbers in messages).
_LINE_BREAK = re.compile(r"\r\n|\r|\n")


@dataclasses.dataclass
class CsvTable:
    """The rows of a CSV file whose header matched one of the accepted column sets.

    Attributes
    ----------
    path
        The file, for messages.
    kind
        The name of the column set the header matched.
    data
        float64 ``(N, C)``, the columns in the order of that column set (not the file's).
    lines
        int64 ``(N,)``, the line number of each row in the file (1-based, counting
        blank and comment lines).
    """

    path: str
    kind: str
    data: np.ndarray
    lines: np.ndarray

    def refuse(self, mask, problem: str) -> None:
        """:class:`FormatError` naming the first row where ``mask`` (bool ``(N,)``) is
        set, the ``problem`` and how many rows share it; nothing when no row is set."""
        mask = np.asarray(mask)
        if mask.any():
            i = int(np.flatnonzero(mask)[0])
            raise FormatError(self.path, f"line {int(self.lines[i])}: {problem} "
                                         f"({int(mask.sum())} such row{'s' if mask.sum() > 1 else ''})")


def read_csv_table(path: str | os.PathLike, column_sets: dict, *, expected: str, noun: str,
                   max_rows: int) -> CsvTable:
    """Read a numeric CSV file whose header names one of ``column_sets``.

    Blank lines and lines starting with ``#`` are ignored (but counted in line numbers).
    The header matches a column set when it names the same columns, in any order,
    case-insensitive, spaces around names ignored, none twice.

    Parameters
    ----------
    column_sets
        ``{kind: column names}``, tried in order; or a function of the header's column
        names (lower case, stripped) returning such a dict (empty: no set matches).
    expected
        What the header should name, for messages (``"a,b or c,d"``).
    noun
        What a row is, for messages (``"sample"``: "no sample rows after the header").
    max_rows
        The most rows accepted; a longer file is refused before it is decoded.

    Returns
    -------
    CsvTable
        Every value parsed, finite or not: the caller checks the values.

    Raises
    ------
    FormatError
        Naming the file, and the line where there is one: unreadable, binary, not UTF-8,
        empty, no header, unknown columns, no rows, too many rows, a row with another
        number of fields or a field that is not a number.
    """
    path = check_input_file(path)
    raw = read_text_bytes(path, "CSV")
    # A runaway file is refused before it is decoded and split into per-line strings
    # (10^7 rows: 29 s and 2.1 GB before this check; docs/stability.md).
    if raw.count(b"\n") + raw.count(b"\r") > max_rows:
        _refuse_too_many(path, _count_value_lines(raw) - 1, noun, max_rows)
    text = decode_text(path, raw)
    del raw
    lines = _LINE_BREAK.split(text)
    numbered = [(i + 1, ln) for i, ln in enumerate(lines) if ln.strip() and not ln.lstrip().startswith("#")]
    del lines, text
    if not numbered:
        raise FormatError(path, f"empty: no header and no {noun} rows")
    header_line, header = numbered[0]
    columns = tuple(c.strip().lower() for c in header.split(","))
    if all(_is_number(c) for c in columns):
        raise FormatError(path, f"line {header_line}: no header; the first line must name the columns "
                                f"({expected})")
    if callable(column_sets):  # sets that depend on the header (wavelength columns)
        column_sets = column_sets(columns)
    kind = next((k for k, want in column_sets.items() if set(columns) == set(want) and len(columns) == len(want)),
                None)
    if kind is None:
        known = set().union(*column_sets.values()) if column_sets else set()
        unknown = [c for c in columns if c not in known]
        what = f"unknown column(s) {', '.join(repr(c) for c in unknown)}" if unknown else \
            f"columns {','.join(columns)} are not a known set"
        raise FormatError(path, f"line {header_line}: {what}; expected {expected}")
    rows = numbered[1:]
    if not rows:
        raise FormatError(path, f"no {noun} rows after the header")
    _refuse_too_many(path, len(rows), noun, max_rows)
    ncol = len(columns)
    linenos = np.fromiter((ln for ln, _ in rows), dtype=np.int64, count=len(rows))
    try:
        data = np.loadtxt([r for _, r in rows], delimiter=",", dtype=np.float64, ndmin=2,
                          comments=None)
    except ValueError as e:
        raise _row_error(path, rows, ncol, e) from None
    if data.shape[1] != ncol:
        raise FormatError(path, f"line {int(linenos[0])}: {data.shape[1]} fields, the header names {ncol}")
    data = data[:, [columns.index(c) for c in column_sets[kind]]]
    return CsvTable(path, kind, data, linenos)


def read_text_bytes(path: str, what: str) -> bytes:
    """The bytes of the text file ``path``; :class:`FormatError` naming it when it cannot be
    read or holds a NUL byte in its first 64 kB (``not a WHAT text file``)."""
    try:
        with open(path, "rb") as f:
            raw = f.read()
    except OSError as e:
        raise FormatError(path, f"cannot read: {e.strerror}") from None
    if b"\x00" in raw[:65536]:
        raise FormatError(path, f"not a {what} text file (binary content)")
    return raw


def decode_text(path: str, raw: bytes) -> str:
    """``raw`` as UTF-8 text (a byte-order mark dropped); :class:`FormatError` naming
    ``path`` and the first bad byte otherwise."""
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise FormatError(path, f"not UTF-8 text (byte {e.start})") from None


def _refuse_too_many(path: str, rows: int, noun: str, max_rows: int) -> None:
    if rows > max_rows:
        raise FormatError(path, f"{rows} {noun} rows, more than the limit of {max_rows} "
                                f"(four times the cells of a MERL table)")


# Bytes that cannot start a value: whitespace, line breaks, '#'.
_NOT_VALUE_START = np.zeros(256, dtype=bool)
_NOT_VALUE_START[[9, 10, 11, 12, 13, 32, ord("#")]] = True


def _count_value_lines(raw: bytes, block: int = 1 << 24) -> int:
    """Lines of ``raw`` whose first byte can start a value: a lower bound of the
    non-blank, non-comment lines (an indented line is not counted), in C-speed blocks
    of bounded memory."""
    a = np.frombuffer(raw, dtype=np.uint8)
    n = int(a.size > 0 and not _NOT_VALUE_START[a[0]])
    for s in range(0, a.size - 1, block):
        chunk = a[s:min(a.size - 1, s + block)]
        after_break = np.flatnonzero((chunk == 10) | (chunk == 13)) + (s + 1)
        n += int(np.count_nonzero(~_NOT_VALUE_START[a[after_break]]))
    return n


def _row_error(path: str, rows, ncol: int, error: ValueError) -> FormatError:
    """The first malformed row, located in Python: ``np.loadtxt`` numbers rows from 0 in
    conversion errors but from 1 in field-count errors, and blames the second row when
    the first one has the wrong number of fields."""
    for line, text in rows:
        fields = text.split(",")
        if len(fields) != ncol:
            return FormatError(path, f"line {line}: {len(fields)} fields, the header names {ncol}")
        for field in fields:
            # float() also takes '1_000' and non-ASCII digits, which loadtxt refuses.
            if "_" in field or not field.isascii() or not _is_number(field):
                return FormatError(path, f"line {line}: {field.strip()!r} is not a number")
    return FormatError(path, str(error).split(" at row")[0].split(";")[0])


def _is_number(s: str) -> bool:
    try:
        float(s)
        return True
    except ValueError:
        return False
