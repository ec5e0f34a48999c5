"""Text tables as programs write them: the one reader under every CSV and whitespace-separated
loader (the AIS reports and the UAV log through :mod:`.csvfile`, the log formats through
:mod:`.logfiles`, MRCLAM's ``.dat`` files, the NGI orientation files, TUM trajectories).

What text exports carry that changes no value is repaired with a count in the caller's ``repairs``
dict (keys ``<what>_<quirk>``, which the experiments put in the metrics' ``data_repairs``) and said
in one :class:`~workbench.errors.DataWarning` line per file:

* a **byte-order mark**, UTF-8 (a spreadsheet's "CSV UTF-8") or UTF-16 (its "Unicode text"):
  ``bom``;
* **empty or blank lines after the last line**: ``trailing_empty_lines`` (how many);
* a **separator** other than the format's: ``;`` (a decimal-comma locale's CSV:
  ``separator_semicolon``), a tab (``separator_tab``), or, where the format is whitespace
  separated, ``;`` or ``,`` (``separator_comma``); each counted once per file;
* **decimal commas** (``1,5`` read as 1.5) where ``,`` is not the separator and no number in the
  file is written with a decimal point: ``decimal_commas`` (the fields);
* **quoted fields** (``"1.5"``): ``quoted_fields`` (the fields).

Line ends (LF, CRLF, a lone CR) are line ends, read as they come and not counted.

What cannot be read unambiguously is a one-line :class:`~workbench.errors.WorkbenchError` naming
the file and the line: binary data, bytes that are not text in the file's encoding, a line split
by another separator than the file's (mixed separators), a row with more fields than the header
(a ``,``-separated file whose numbers hold decimal commas: ``50,77`` would shift every column
after it), numbers written with both decimal marks, a number with both marks (``1.234,5``), a
quoted field running over its line's end.

The fast path: a file none of whose quirks need a field's attention (no ``"``, and no ``,`` where
``,`` is not the separator) is split with ``str.split`` and nothing else;
:func:`plain` says so from the bytes alone for callers that have a faster parser of their own
(MRCLAM's ``np.loadtxt``).
"""

from __future__ import annotations

import codecs
import csv
import re
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from workbench.errors import DataWarning, WorkbenchError

WHITESPACE = None
"""The separator of a whitespace-separated format (any run of spaces and tabs)."""
NAMES = {",": "comma", ";": "semicolon", "\t": "tab", WHITESPACE: "whitespace"}
SHOWN = {",": "','", ";": "';'", "\t": "a tab", WHITESPACE: "whitespace"}

_BOMS = ((codecs.BOM_UTF8, "utf-8"), (codecs.BOM_UTF16_LE, "utf-16-le"), (codecs.BOM_UTF16_BE, "utf-16-be"))
_COMMA_NUMBER = re.compile(r"[+-]?(?:\d+,\d*|,\d+)(?:[eE][+-]?\d+)?")
_POINT_NUMBER = re.compile(r"[+-]?(?:\d+\.\d*|\.\d+)(?:[eE][+-]?\d+)?")
_BOTH_MARKS = re.compile(r"[+-]?\d[\d.,]*(?:\.\d*,|,\d*\.)[\d.,]*")


@dataclass
class Table:
    """A text table's lines, split into fields, each row with its line number in the file.

    ``header`` is the first line's fields (stripped) where the format has one; ``rows`` holds
    every other line that is not blank or a comment, as ``(line number, fields)`` with the
    fields stripped, unquoted and decimal commas turned to points. ``ended``: the last line ends
    with a line end (a file cut mid-line does not). ``lines`` are the file's decoded lines
    (``lines[n - 1]`` is line ``n``), for messages that show one.
    """

    path: Path
    header: list[str] | None
    rows: list[tuple[int, list[str]]]
    separator: str | None
    ended: bool
    lines: list[str] = field(repr=False, default_factory=list)


def plain(raw: bytes, separator: str | None = WHITESPACE) -> bool:
    """Whether a file's bytes need none of this module's repairs (checked at C speed): no BOM,
    no NUL, no ``"``, no ``;``, no ``,`` unless it is the separator, no blank line at the end.
    Line ends may be CRLF."""
    if raw.startswith((codecs.BOM_UTF8, codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)) or b"\0" in raw:
        return False
    if b'"' in raw or (separator != ";" and b";" in raw) or (separator != "," and b"," in raw):
        return False
    tail = raw[len(raw.rstrip(b" \t\r\n")):]
    return tail.count(b"\n") + tail.count(b"\r") - tail.count(b"\r\n") <= 1


def decode(path: Path, raw: bytes, what: str, repairs: dict[str, int], encoding: str = "utf-8"
           ) -> tuple[list[str], bool, list[str]]:
    """The file's lines (line ends dropped, blank lines at the end dropped and counted), whether
    the last one ended with a line end, and what was repaired (for the warning)."""
    said = []
    for bom, codec in _BOMS:
        if raw.startswith(bom):
            raw, encoding = raw[len(bom):], codec
            _count(repairs, f"{what}_bom", 1)
            said.append(f"a {'UTF-8' if codec == 'utf-8' else 'UTF-16'} byte-order mark")
            break
    else:
        if b"\0" in raw:
            line = raw[:raw.index(b"\0")].count(b"\n") + 1
            raise WorkbenchError(f"{path}, line {line}: binary data (a NUL byte), not a text table")
    try:
        text = raw.decode(encoding)
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise WorkbenchError(f"{path}, line {line}: not {encoding.upper()} text "
                             f"(byte {raw[exc.start]:#04x})") from None
    if "\r" in text:
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    lines = text.split("\n")
    ended = len(lines) > 1 and lines[-1] == ""
    if ended:
        lines.pop()
    blank = 0
    while lines and not lines[-1].strip():
        lines.pop()
        blank += 1
    if blank and lines:
        ended = True
        _count(repairs, f"{what}_trailing_empty_lines", blank)
        said.append(f"{blank} empty line(s) at the end")
    return lines, ended, said


def table(path: Path, what: str, repairs: dict[str, int], *, columns: Sequence[str] | None = None,
          separator: str | None = ",", comments: str | None = None, encoding: str = "utf-8",
          quiet: bool = False) -> Table:
    """Read ``path`` as a table of ``separator``-separated fields (``WHITESPACE``: runs of spaces
    and tabs), its quirks repaired and counted under ``what`` (see the module).

    ``columns``: the file has a header line (its first) that must hold these names; the separator
    is the one of ``,``, ``;``, tab whose split of the header holds them all. Without ``columns``
    the separator is found on the first row: ``;`` where it has one; in a ``,``-separated format a
    tab where the row has no ``,``; in a whitespace-separated format ``,`` where the commas stand
    between the fields (``1.0,2.0`` or ``1.0, 2.0``; in ``1,5 2,5`` they are decimal commas); else
    the format's. ``comments``: a character that starts a comment to the end of the line.
    ``quiet``: count, but say nothing (a second read to name a line).
    """
    raw = path.read_bytes()
    lines, ended, said = decode(path, raw, what, repairs, encoding)
    start = 0
    if columns is not None:
        if not lines or not lines[0].strip():
            return Table(path, None, [], separator, ended, lines)
        sep = _header_separator(lines[0], columns, separator)
        start = 1
    else:
        sep = _row_separator(lines, separator, comments)
    if sep != separator:
        _count(repairs, f"{what}_separator_{NAMES[sep]}", 1)
        said.append(f"separated by {SHOWN[sep]}")
    quoted = 0
    header = None
    if columns is not None:
        header, quoted = _fields(path, lines, 0, sep, ended)
    rows, in_rows = _rows(path, lines, start, sep, comments, ended, None if header is None else len(header))
    quoted += in_rows
    if quoted:
        _count(repairs, f"{what}_quoted_fields", quoted)
        said.append(f"{quoted} quoted field(s)")
    if sep != "," and b"," in raw:
        commas = _decimal_commas(path, rows)
        if commas:
            _count(repairs, f"{what}_decimal_commas", commas)
            said.append(f"{commas} decimal comma(s)")
    if said and not quiet:
        warnings.warn(DataWarning(f"{path.name}: {', '.join(said)}: read past (a text export's quirks)"),
                      stacklevel=3)
    return Table(path, header, rows, sep, ended, lines)


def _count(repairs: dict[str, int], key: str, n: int) -> None:
    if n:
        repairs[key] = repairs.get(key, 0) + int(n)


def _split(line: str, sep: str | None) -> list[str]:
    """A line's fields, stripped, quoted ones unquoted (the csv module's quoting)."""
    if sep is WHITESPACE:
        return [f[1:-1].replace('""', '"').strip() if len(f) >= 2 and f[0] == f[-1] == '"' else f
                for f in line.split()]
    if '"' not in line:
        return [f.strip() for f in line.split(sep)]
    return [f.strip() for f in next(csv.reader([line], delimiter=sep, skipinitialspace=True))]


def _quoted(line: str, sep: str | None) -> int:
    """How many of a line's fields are quoted."""
    if sep is WHITESPACE:
        return sum(len(f) >= 2 and f[0] == f[-1] == '"' for f in line.split())
    s = re.escape(sep)
    return len(re.findall(rf'(?:^|{s})[ \t]*"(?:[^"]|"")*"[ \t]*(?={s}|$)', line))


def _fields(path: Path, lines: list[str], i: int, sep: str | None, ended: bool) -> tuple[list[str], int]:
    """Line ``i``'s (0-based) fields and how many were quoted; a quote left open is refused but
    on a last line cut short (its field is read as far as it goes)."""
    line = lines[i]
    if '"' not in line:
        return _split(line, sep), 0
    if line.count('"') % 2 and (ended or i < len(lines) - 1):
        raise WorkbenchError(f"{path}, line {i + 1}: a quote that does not close on its line (a field running "
                             "over the line\'s end?): ambiguous, not read")
    return _split(line, sep), _quoted(line, sep)


def _outside_quotes(line: str) -> str:
    return re.sub(r'"[^"]*"', "", line) if '"' in line else line


def _header_separator(header: str, columns: Sequence[str], default: str | None) -> str | None:
    """The separator whose split of the header line holds every needed column (the format's own
    first); the format's where none does, so that the missing columns are named in its split."""
    for sep in dict.fromkeys((default, ",", ";", "\t")):
        if set(columns) <= set(_split(header, sep)):
            return sep
    return default


def _row_separator(lines: list[str], default: str | None, comments: str | None) -> str | None:
    """The separator of a table without a header, from its first row: ``;`` where it has one;
    a tab in a ``,``-separated format where it has no ``,``; ``,`` in a whitespace-separated
    format where the commas stand between the fields (``1.0,2.0`` or ``1.0, 2.0``, not ``1,5 2,5``)."""
    for line in lines:
        line = _outside_quotes(line.split(comments, 1)[0] if comments else line)
        if not line.strip():
            continue
        if ";" in line:
            return ";"
        if default == "," and "\t" in line and "," not in line:
            return "\t"
        if default is WHITESPACE and "," in line:
            tokens = line.split()
            if len(tokens) == 1 or any(t.startswith(",") or t.endswith(",") for t in tokens):
                return ","
        return default
    return default


def _rows(path: Path, lines: list[str], start: int, sep: str | None, comments: str | None, ended: bool,
          width: int | None) -> tuple[list[tuple[int, list[str]]], int]:
    """Every row from line ``start`` (0-based) on that is not blank or a comment, as (line number,
    fields), and how many fields were quoted. ``width``: the header's fields; a row with more
    (not empty) is refused, one with fewer that another separator would fill is refused as mixed."""
    rows, quoted = [], 0
    for i in range(start, len(lines)):
        line = lines[i]
        if comments and comments in line:
            line = line.split(comments, 1)[0]
        if not line.strip():
            continue
        if '"' in line:
            fields, q = _fields(path, lines, i, sep, ended)
            quoted += q
        else:
            fields = _split(line, sep)
        bare = _outside_quotes(line)
        if sep != ";" and ";" in bare:
            _mixed(path, i, ";", sep)
        if width is None and sep is not WHITESPACE and len(fields) == 1 and len(bare.split()) >= 2:
            _mixed(path, i, WHITESPACE, sep)
        if width is not None and len(fields) > width and any(fields[width:]):
            hint = " (a \',\' inside a number? decimal commas need a \';\' separator)" if sep == "," else ""
            raise WorkbenchError(f"{path}, line {i + 1}: {len(fields)} fields, the header has {width}{hint}: "
                                 "ambiguous, not read")
        if width is not None and len(fields) < width:
            for other in (",", "\t", WHITESPACE):
                if other != sep and len(_split(bare, other)) >= width:
                    _mixed(path, i, other, sep)
        rows.append((i + 1, fields))
    return rows, quoted


def _mixed(path: Path, i: int, found: str | None, sep: str | None) -> None:
    raise WorkbenchError(f"{path}, line {i + 1}: separated by {SHOWN[found]} where the file is by {SHOWN[sep]} "
                         "(mixed separators): ambiguous, not read")


def _decimal_commas(path: Path, rows: list[tuple[int, list[str]]]) -> int:
    """Turn decimal commas into points in place (where ``,`` is not the separator); how many.
    Refused: a file writing numbers with both marks, a number with both (a thousands mark?)."""
    comma_at = point_at = None
    n = 0
    for line, fields in rows:
        for k, f in enumerate(fields):
            if "," in f:
                if _COMMA_NUMBER.fullmatch(f):
                    fields[k] = f.replace(",", ".")
                    n += 1
                    comma_at = comma_at or (line, f)
                elif _BOTH_MARKS.fullmatch(f):
                    raise WorkbenchError(f"{path}, line {line}: {f!r} has both a ',' and a '.' (a thousands "
                                         "mark?): ambiguous, not read")
            elif point_at is None and "." in f and _POINT_NUMBER.fullmatch(f):
                point_at = (line, f)
        if comma_at and point_at:
            first, second = sorted([comma_at, point_at])
            raise WorkbenchError(f"{path}, line {second[0]}: {second[1]!r} and {first[1]!r} on line {first[0]} "
                                 "write numbers with different decimal marks: ambiguous, not read")
    return n
