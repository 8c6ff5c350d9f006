"""Type and range checks of user-supplied values, in one place.

``Options``, ``Network``, ``Curve`` and the file readers (io.py, the command
line) call these helpers when a value is read, so a wrong type (a number
given as a string, ``null``, a list for an object) or an impossible value
(a negative tolerance, an infinite edge length, 2.7 iterations) is refused
at once, with a message that names the key, shows the value and says what
is expected -- never a TypeError from deep inside the solve, and never after
minutes of meshing.

Every helper takes ``name`` (how the user wrote the key: ``option
'edge_length'``, ``curve 3 'axis': sigma``) and ``error`` (the SymFramesError
subclass to raise) and returns the value converted to a plain Python type.
"""

from __future__ import annotations

import math
from numbers import Integral, Real

import numpy as np

from .errors import SymFramesError


def describe(value) -> str:
    """The value as the user wrote it, with its type when that is the problem."""
    if value is None:
        return "null/None"
    if isinstance(value, bool):
        return f"{value} (a boolean)"
    if isinstance(value, str):
        return f"{value!r} (a string)"
    if isinstance(value, (list, tuple, dict, np.ndarray)):
        text = repr(value if not isinstance(value, np.ndarray) else value.tolist())
        kind = {"list": "a list", "tuple": "a tuple", "dict": "an object"}.get(type(value).__name__, "an array")
        return f"{text[:60]}{'...' if len(text) > 60 else ''} ({kind})"
    if isinstance(value, (Integral, np.integer)) and abs(int(value)) >= 10**15:
        # a huge whole number: its size, not hundreds of digits (str() of one refuses past 4,300)
        return f"{'-' if value < 0 else ''}~10**{int(abs(int(value)).bit_length() * math.log10(2))} (a whole number)"
    return repr(value)


def _fail(error, name, value, expected, fix=None):
    msg = f"{name} = {describe(value)}: must be {expected}"
    raise error(msg + (f"; {fix}" if fix else ""))


def _is_real(value) -> bool:
    return isinstance(value, (Real, np.floating, np.integer)) and not isinstance(value, (bool, np.bool_))


def real(name: str, value, error=SymFramesError, *, low=None, high=None, low_open=False, high_open=False,
         allow_none=False, fix=None) -> float | None:
    """A finite real number in [low, high] (open ends on request)."""
    if value is None and allow_none:
        return None
    parts = []
    if low is not None:
        parts.append(f"{'>' if low_open else '>='} {low:g}")
    if high is not None:
        parts.append(f"{'<' if high_open else '<='} {high:g}")
    expected = "a finite number" + (" " + " and ".join(parts) if parts else "")
    if allow_none and not fix:
        expected += " (or null/None for the default)"
    if isinstance(value, str):
        hint = fix
        try:
            float(value)
            hint = f"write it without quotes, e.g. {value.strip()}" + (f"; {fix}" if fix else "")
        except ValueError:
            pass
        _fail(error, name, value, expected, hint)
    if not _is_real(value):
        _fail(error, name, value, expected, fix)
    try:
        x = float(value)
    except OverflowError:  # a whole number past 1.8e308
        _fail(error, name, value, expected, fix)
    if not math.isfinite(x):
        _fail(error, name, value, expected, fix)
    if low is not None and (x < low or (low_open and x == low)):
        _fail(error, name, value, expected, fix)
    if high is not None and (x > high or (high_open and x == high)):
        _fail(error, name, value, expected, fix)
    return x


def positive_float(name: str, value, error=SymFramesError, *, allow_none=False, high=None, fix=None):
    """A finite number > 0 (and <= high if given)."""
    return real(name, value, error, low=0.0, low_open=True, high=high, allow_none=allow_none, fix=fix)


def nonnegative_float(name: str, value, error=SymFramesError, *, allow_none=False, fix=None):
    """A finite number >= 0."""
    return real(name, value, error, low=0.0, allow_none=allow_none, fix=fix)


def integer(name: str, value, error=SymFramesError, *, low=None, high=None, allow_none=False, fix=None):
    """A whole number in [low, high]; 3.0 is accepted as 3, 2.7 and "3" are not."""
    if value is None and allow_none:
        return None
    parts = ([f">= {low}"] if low is not None else []) + ([f"<= {high}"] if high is not None else [])
    expected = "a whole number" + (" " + " and ".join(parts) if parts else "")
    if allow_none and not fix:
        expected += " (or null/None for the default)"
    if isinstance(value, (Integral, np.integer)) and not isinstance(value, (bool, np.bool_)):
        k = int(value)
    elif _is_real(value) and math.isfinite(float(value)) and float(value).is_integer():
        k = int(value)
    else:
        if isinstance(value, str) and value.strip().lstrip("+-").isdigit():
            fix = f"write it without quotes, e.g. {value.strip()}" + (f"; {fix}" if fix else "")
        _fail(error, name, value, expected, fix)
    if (low is not None and k < low) or (high is not None and k > high):
        _fail(error, name, value, expected, fix)
    if abs(k) >= 2**63:  # no count or index of a solve comes near; float(k) could overflow
        _fail(error, name, value, expected + " (below 2**63)", fix)
    return k


def boolean(name: str, value, error=SymFramesError) -> bool:
    """true/false only: the string "false" is refused (it would read as True)."""
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    _fail(error, name, value, "true or false (a boolean, not a string or a number)")


def choice(name: str, value, allowed, error=SymFramesError) -> str:
    """One of the allowed strings."""
    allowed = list(allowed)
    if isinstance(value, str) and value in allowed:
        return value
    _fail(error, name, value, "one of " + ", ".join(repr(a) for a in allowed))


def text(name: str, value, error=SymFramesError) -> str:
    if isinstance(value, str):
        return value
    _fail(error, name, value, "a string")


def _rows(name: str, value, error, expected: str) -> list:
    """The items of a list-like value, or the error saying what was expected."""
    try:
        return list(value)
    except TypeError:
        _fail(error, name, value, expected)


def points3(name: str, value, error=SymFramesError, *, min_points=2) -> np.ndarray:
    """An (n, 3) float array of finite points, n >= min_points."""
    expected = f"a list of at least {min_points} points [x, y, z] (an (n, 3) array of finite numbers)"
    if isinstance(value, (str, bytes, dict)) or value is None:
        _fail(error, name, value, expected)
    if not isinstance(value, np.ndarray):
        rows = _rows(name, value, error, expected)
        for k, row in enumerate(rows):
            if isinstance(row, (str, bytes, dict)) or not hasattr(row, "__len__") or len(row) != 3 or not all(
                    _is_real(x) for x in (row.tolist() if isinstance(row, np.ndarray) else row)):
                raise error(f"{name}: point {k} is {describe(row)}; each point must be [x, y, z], three numbers")
        value = np.asarray(rows, dtype=float).reshape(-1, 3) if rows else np.zeros((0, 3))
    elif value.dtype == object or not (np.issubdtype(value.dtype, np.number) and not np.issubdtype(
            value.dtype, np.complexfloating)):
        _fail(error, name, value, expected)
    P = np.array(value, dtype=float)
    if P.ndim != 2 or P.shape[1] != 3:
        _fail(error, name, value, expected + f", got shape {P.shape}")
    if len(P) < min_points:
        _fail(error, name, value, expected + f", got {len(P)}")
    bad = np.nonzero(~np.all(np.isfinite(P), axis=1))[0]
    if len(bad):
        raise error(f"{name}: point {bad[0]} {P[bad[0]].tolist()} has a non-finite coordinate")
    bad = np.nonzero(np.any(np.abs(P) > 1e100, axis=1))[0]
    if len(bad):  # squared distances would overflow
        raise error(f"{name}: point {bad[0]} {P[bad[0]].tolist()} is beyond +-1e+100; a stray point, or a curve in "
                    "other units than the surface")
    return P


def index_pairs(name: str, value, error=SymFramesError) -> np.ndarray:
    """A (k, 2) array of non-negative vertex indices."""
    expected = "a list of vertex index pairs [[i, j], ...] (whole numbers >= 0)"
    if isinstance(value, (str, bytes, dict)):
        _fail(error, name, value, expected)
    if not isinstance(value, np.ndarray):
        rows = _rows(name, value, error, expected)
        for k, row in enumerate(rows):
            ok = isinstance(row, (list, tuple, np.ndarray)) and len(row) == 2
            vals = list(row) if ok else []
            if not ok or not all(isinstance(x, (Integral, np.integer)) and not isinstance(x, (bool, np.bool_))
                                 for x in vals):
                raise error(f"{name}: entry {k} is {describe(row)}; each entry must be a pair of vertex indices "
                            "[i, j] (whole numbers, 0-based)")
            big = [x for x in vals if abs(int(x)) >= 2**63]
            if big:
                raise error(f"{name}: entry {k} has the vertex index {describe(big[0])}, past any vertex; indices "
                            "are 0-based vertex numbers of the surface")
        value = np.asarray(rows, dtype=np.int64).reshape(-1, 2) if rows else np.zeros((0, 2), np.int64)
    elif value.size == 0:
        value = np.zeros((0, 2), np.int64)
    elif value.size % 2 or not (np.issubdtype(value.dtype, np.integer) or (np.issubdtype(value.dtype, np.floating)
                                and np.all(np.isfinite(value)) and np.all(value == np.round(value))
                                and np.all(np.abs(value) < 2.0**63))):
        _fail(error, name, value, expected)
    A = np.asarray(value, dtype=np.int64).reshape(-1, 2)
    if len(A) and A.min() < 0:
        k = int(np.nonzero((A < 0).any(axis=1))[0][0])
        raise error(f"{name}: entry {k} {A[k].tolist()} has a negative vertex index; indices are 0-based")
    return A


def mapping(name: str, value, error=SymFramesError) -> dict:
    if isinstance(value, dict):
        return value
    _fail(error, name, value, "an object {\"key\": value, ...}")


def sequence(name: str, value, error=SymFramesError) -> list:
    if isinstance(value, (list, tuple)):
        return list(value)
    _fail(error, name, value, "a list [...]")


def instance(name: str, value, types, error=SymFramesError, fix: str | None = None):
    """value if it is one of ``types`` (a class or a tuple of them), else
    ``error`` naming the argument, what it is and what it must be."""
    if isinstance(value, types):
        return value
    kinds = types if isinstance(types, tuple) else (types,)
    plain = not hasattr(value, "__dict__") or isinstance(value, np.ndarray)
    shown = describe(value) if plain else f"a {type(value).__name__}"
    msg = f"{name} = {shown}: must be " + " or ".join(f"a {k.__name__}" for k in kinds)
    raise error(msg + (f"; {fix}" if fix else ""))


def array(name: str, value, error=SymFramesError, *, shape: tuple, kind: str = "f", finite: bool = True) -> np.ndarray:
    """value as a numpy array of dtype kind ``kind`` ('f' real numbers, 'i'
    whole numbers) and shape ``shape`` (None: any length there)."""
    want = "(" + ", ".join("n" if s is None else str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"
    expected = f"an array of shape {want} of {'numbers' if kind == 'f' else 'whole numbers'}"
    try:
        a = np.asarray(value)
    except (ValueError, TypeError):
        _fail(error, name, value, expected)
    if a.ndim != len(shape) or any(s is not None and s != g for s, g in zip(shape, a.shape)):
        _fail(error, name, value, expected)
    if kind == "i" and a.dtype.kind in "fb" or a.size == 0 and a.dtype.kind not in "fiub":
        whole = a.size == 0 or a.dtype.kind == "f" and np.isfinite(a).all() and np.all(a == np.round(a))
        if not whole:
            _fail(error, name, value, expected)
        a = a.astype(np.int64)
    if a.dtype.kind not in ("fiu" if kind == "f" else "iu"):
        _fail(error, name, value, expected)
    if kind == "f":
        a = a.astype(float)
        if finite and not np.isfinite(a).all():
            _fail(error, name, value, expected + ", all finite")
    return a


def path(name: str, value, error=SymFramesError) -> str:
    """A file path: a non-empty str (or os.PathLike), never an int (which
    open() would take as a file descriptor)."""
    import os

    if isinstance(value, (str, os.PathLike)) and os.fspath(value):
        return os.fspath(value)
    _fail(error, name, value, "a file path (a non-empty string)")
