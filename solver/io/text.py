"""Text files: reading them (the encoding, numbers with their line), and writing rows of numbers.

``read_text`` decodes a file as a user's tools may have saved it: UTF-8
(with or without a byte-order mark), UTF-16 or UTF-32 with a byte-order
mark, or UTF-16 without one (Windows tools write it; recognised by its NUL
bytes).  A file that is none of these is refused as not text, naming it.

``Tokens`` holds a file's whitespace-separated words with the line each
came from, so a reader can name the line of any value it refuses, and
converts runs of them to numbers in one numpy call (a Python loop runs only
to find the culprit once a conversion has failed).

``format_rows`` writes the rows of a numeric array as text lines, one
printf format per value, in one C-level formatting call: the writers of
every text format here use it.
"""

from __future__ import annotations

import codecs
import os

import numpy as np

_BOMS = ((codecs.BOM_UTF32_LE, "utf-32"), (codecs.BOM_UTF32_BE, "utf-32"), (codecs.BOM_UTF8, "utf-8-sig"),
         (codecs.BOM_UTF16_LE, "utf-16"), (codecs.BOM_UTF16_BE, "utf-16"))


def read_text(path, error, what: str, kind: str = "text") -> str:
    """The text of a file, decoded (module docs).

    path  : the file
    error : the SymFramesError subclass to raise
    what  : what the file is, for messages ("surface file", "tet mesh")
    kind  : what text it must be ("JSON text"), for messages
    """
    if not isinstance(path, (str, bytes, os.PathLike)) or not os.fspath(path):
        raise error(f"{what} {path!r}: must be a file path (a non-empty string)")
    try:
        with open(path, "rb") as fh:
            raw = fh.read()
    except IsADirectoryError:
        raise error(f"cannot read {what} {path!r}: it is a folder; give a file") from None
    except OSError as e:
        raise error(f"cannot read {what} {path!r}: {e.strerror or e}") from None
    except TypeError:
        raise error(f"{what} {path!r}: must be a file path (a string)") from None
    for bom, enc in _BOMS:
        if raw.startswith(bom):
            return _decode(raw, enc, path, error, what, kind)
    if b"\0" in raw[:4096]:
        # UTF-16 without a byte-order mark: ASCII text has a NUL after (LE) or before (BE) every character
        head = raw[:4096]
        if head[1::2].count(0) > 0.4 * len(head[1::2]):
            return _decode(raw, "utf-16-le", path, error, what, kind)
        if head[0::2].count(0) > 0.4 * len(head[0::2]):
            return _decode(raw, "utf-16-be", path, error, what, kind)
        raise error(f"{path}: not a {kind} file (it holds binary data); the {what} must be a {kind} file")
    return _decode(raw, "utf-8", path, error, what, kind)


def _decode(raw: bytes, encoding: str, path, error, what: str, kind: str = "text") -> str:
    try:
        return raw.decode(encoding)
    except UnicodeDecodeError as e:
        if encoding == "utf-8":
            # Latin-1 and kin: the words that matter are ASCII; keep them, mark the rest
            text = raw.decode("utf-8", errors="replace")
            if text.count("\ufffd") <= max(8, len(text) // 100):
                return text
        line = raw[:e.start].count(b"\n") + 1 if encoding == "utf-8" else "?"
        raise error(f"{path}:{line}: not a {kind} file ({encoding} cannot decode byte {raw[e.start:e.start + 1]!r}); "
                    f"the {what} must be a {kind} file") from None


class Tokens:
    """The words of a text with the line of each (module docs).

    comment : a character that starts a comment to the end of its line, or None
    """

    def __init__(self, text: str, path: str, error, comment: str | None = "#"):
        words, lines = [], []
        self.text_lines = text.splitlines()
        for k, line in enumerate(self.text_lines, 1):
            if comment is not None:
                line = line.split(comment, 1)[0]
            parts = line.split()
            words.extend(parts)
            lines.extend([k] * len(parts))
        self.words = words
        self.lines = np.asarray(lines, np.int64)
        self.path = os.fspath(path)
        self.error = error
        self.pos = 0

    @classmethod
    def of_file(cls, path, error, what: str) -> Tokens:
        """The words of a text file (``read_text``: ``error`` and ``what`` as
        there), with their lines."""
        return cls(read_text(path, error, what), path, error)

    def __len__(self) -> int:
        return len(self.words)

    @property
    def done(self) -> bool:
        return self.pos >= len(self.words)

    def line(self, i: int | None = None) -> int:
        """Line of word i (default: the next one; the last line past the end)."""
        i = self.pos if i is None else i
        if not len(self.lines):
            return 1
        return int(self.lines[min(i, len(self.lines) - 1)])

    def raw_line(self, k: int) -> str:
        """Line k (1-based) as written."""
        return self.text_lines[k - 1]

    def fail(self, message: str, i: int | None = None):
        raise self.error(f"{self.path}:{self.line(i)}: {message}")

    def end(self, what: str) -> None:
        """Refuse words left after ``what`` (the last entry a header announced)."""
        if not self.done:
            self.fail(f"{self.words[self.pos]!r} after {what}: the count in the header is smaller than the data (or "
                      "the file has extra data)")

    def next(self, what: str) -> str:
        if self.done:
            self.fail(f"the file ends where {what} was expected (truncated?)")
        self.pos += 1
        return self.words[self.pos - 1]

    def count(self, what: str, per: int = 1) -> int:
        """A non-negative whole number (a section's entry count); ``per``
        words follow per entry, and the file must hold that many."""
        i = self.pos
        word = self.next(f"the number of {what}")
        try:
            n = int(word)
        except ValueError:
            self.fail(f"{word!r} where the number of {what} was expected (a whole number >= 0)", i)
        if n < 0:
            self.fail(f"the number of {what} is {n}; it must be >= 0", i)
        left = len(self.words) - self.pos
        if n * per > left:
            self.fail(f"{n:,} {what} announced, {n * per:,} values, but the file holds only {left:,} more values "
                      "(truncated, or a wrong count)", i)
        return n

    def block(self, n: int, width: int, what: str, kind: str = "float") -> np.ndarray:
        """The next n * width words as an (n, width) array of finite floats
        (kind 'float') or whole numbers (kind 'int', int64)."""
        a, b = self.pos, self.pos + n * width
        if b > len(self.words):
            self.fail(f"the file ends inside the {what} ({n:,} entries of {width} values announced)")
        self.pos = b
        return numbers(self.words[a:b], self.lines[a:b], kind, what, self.path, self.error).reshape(n, width)


def numbers(words: list, lines: np.ndarray, kind: str, what: str, path: str, error) -> np.ndarray:
    """words as finite floats, or as int64 whole numbers (kind 'int'; "3.0"
    is 3, "1.5" is refused); a word that is not one is refused with its line
    (module docs)."""
    if not words:
        return np.zeros(0, np.int64 if kind == "int" else float)
    if kind == "int":
        try:
            return np.array(words, dtype=np.int64)
        except (ValueError, OverflowError):
            pass
    try:
        x = np.array(words, dtype=float)
    except (ValueError, OverflowError):
        x = None
    if x is not None and np.all(np.isfinite(x)):
        if kind != "int":
            return x
        if np.all(x == np.round(x)) and np.all(np.abs(x) < 2.0**63):
            return x.astype(np.int64)
    for k, w in enumerate(words):  # only on failure: find the culprit
        try:
            v = float(w)
        except ValueError:
            hint = "; a keyword here means the count before it is too large" if w[:1].isalpha() else ""
            raise error(f"{path}:{lines[k]}: {w!r} in the {what}: must be a number{hint}") from None
        if not np.isfinite(v):
            raise error(f"{path}:{lines[k]}: {w!r} in the {what}: must be a finite number")
        if kind == "int" and v != round(v):
            raise error(f"{path}:{lines[k]}: {w} in the {what}: must be a whole number (an index or a tag), not a "
                        "fraction")
        if kind == "int" and abs(v) >= 2.0**63:
            raise error(f"{path}:{lines[k]}: {w} in the {what}: out of range (a whole number below 2**63 in size)")
    raise error(f"{path}: the {what} hold values that are not numbers")


def format_rows(a: np.ndarray, fmt: str) -> str:
    """Rows of a 2D array as text lines (C-level formatting, no Python loop per row)."""
    a = np.asarray(a)
    if len(a) == 0:
        return ""
    a = a.reshape(len(a), -1)
    line = " ".join([fmt] * a.shape[1]) + "\n"
    return (line * len(a)) % tuple(a.reshape(-1).tolist())
